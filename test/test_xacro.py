"""xacro descriptions: sik-build expands them (with --xacro-arg), the robot_description check too.

The fixture arm is a 4-joint xacro description with an include, a macro and two arguments (its
reach and a joint limit); failures are one line naming the file and the problem, exit 2.
"""

import json
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

from sik_ros.cli.build import main as build_main
from sik_ros.errors import InvalidArgument, InvalidModel
from sik_ros.kinematics.description import (expand_xacro, is_xacro_text, parse_xacro_args,
                                            resolve_package_uris, write_xacro_urdf)
from sik_ros.kinematics.robots import chain_differences, load_robot

MACROS = """<?xml version="1.0"?>
<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:macro name="segment" params="name parent length limit">
    <link name="${name}">
      <collision><origin xyz="0 0 ${length/2}"/>
        <geometry><cylinder radius="0.03" length="${length}"/></geometry></collision>
      <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0"
        iyz="0"/></inertial>
    </link>
    <joint name="${name}_joint" type="revolute">
      <parent link="${parent}"/><child link="${name}"/>
      <origin xyz="0 0 ${length}"/><axis xyz="0 1 0"/>
      <limit lower="${-limit}" upper="${limit}" effort="10" velocity="2"/>
    </joint>
  </xacro:macro>
</robot>
"""
ARM = """<?xml version="1.0"?>
<robot name="xarm4" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:arg name="reach" default="0.3"/>
  <xacro:arg name="limit" default="2.0"/>
  <xacro:property name="l" value="$(arg reach)"/>
  <xacro:include filename="macros.xacro"/>
  <link name="base_link"/>
  <link name="turn">
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0"
      iyz="0"/></inertial>
  </link>
  <joint name="turn_joint" type="revolute">
    <parent link="base_link"/><child link="turn"/><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
    <limit lower="-2.5" upper="2.5" effort="10" velocity="2"/>
  </joint>
  <xacro:segment name="upper" parent="turn" length="${l}" limit="$(arg limit)"/>
  <xacro:segment name="fore" parent="upper" length="${l}" limit="$(arg limit)"/>
  <xacro:segment name="wrist" parent="fore" length="0.1" limit="$(arg limit)"/>
  <link name="tool0"/>
  <joint name="tool_joint" type="fixed">
    <parent link="wrist"/><child link="tool0"/><origin xyz="0 0 0.1"/>
  </joint>
</robot>
"""


@pytest.fixture
def description(tmp_path):
    """The fixture arm's xacro files in ``tmp_path/description/urdf``."""
    folder = tmp_path / 'description' / 'urdf'
    folder.mkdir(parents=True)
    (folder / 'macros.xacro').write_text(MACROS)
    (folder / 'arm.urdf.xacro').write_text(ARM)
    return folder / 'arm.urdf.xacro'


def sik_build(*args, cwd=None):
    return subprocess.run([sys.executable, '-m', 'sik_ros.cli.build', *args], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


def test_expansion_takes_arguments(description, tmp_path):
    """Arguments reach the expanded URDF: the chain's placements and limits follow them."""
    urdf = write_xacro_urdf(description, tmp_path / 'arm.urdf', {'reach': '0.4', 'limit': '1.5'})
    robot = load_robot(urdf=str(urdf))
    assert robot.joint_names == ['turn_joint', 'upper_joint', 'fore_joint', 'wrist_joint']
    assert robot.base_frame == 'base_link' and robot.tip_frame == 'tool0'
    np.testing.assert_allclose(robot.upper, [2.5, 1.5, 1.5, 1.5])
    position, _ = robot.fk(np.zeros(4))
    np.testing.assert_allclose(position, [0.0, 0.0, 0.1 + 0.4 + 0.4 + 0.1 + 0.1], atol=1e-12)


def test_robot_description_as_xacro(description, tmp_path, monkeypatch):
    """A xacro robot_description is expanded for the chain check: alike, then a changed limit."""
    urdf = write_xacro_urdf(description, tmp_path / 'arm.urdf')
    robot = load_robot(urdf=str(urdf))
    monkeypatch.chdir(description.parent)          # the text's includes, from the current folder
    assert is_xacro_text(ARM)
    assert chain_differences(robot, ARM) == []
    changed = ARM.replace('name="limit" default="2.0"', 'name="limit" default="1.0"')
    assert chain_differences(robot, changed) == [
        "joint lower limits differ at ['upper_joint', 'fore_joint', 'wrist_joint']",
        "joint upper limits differ at ['upper_joint', 'fore_joint', 'wrist_joint']"]


@pytest.mark.parametrize('break_it, where, problem', [
    (lambda d: (d / 'macros.xacro').unlink(), 'arm.urdf.xacro', 'No such file'),
    (lambda d: (d / 'macros.xacro').write_text(MACROS.replace('${length/2}', '${length/}')),
     'macros.xacro', "evaluating expression 'length/'"),
    (lambda d: (d / 'arm.urdf.xacro').write_text(ARM.replace('</robot>', '')),
     'arm.urdf.xacro', 'no element found'),
    (lambda d: (d / 'arm.urdf.xacro').write_text(ARM.replace('$(arg reach)', '$(arg span)')),
     'arm.urdf.xacro', 'span'),
])
def test_xacro_failure_is_one_line(description, tmp_path, capsys, break_it, where, problem):
    """sik-build on a broken xacro: one line naming the failing file and the problem, exit 2."""
    break_it(description.parent)
    code = build_main(['--urdf', str(description), '--out', str(tmp_path / 'b'), '--time', '10'])
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith('sik-build: ') and where in lines[0] and problem in lines[0], lines
    assert not (tmp_path / 'b').exists()


def test_bad_arguments(capsys):
    """A malformed --xacro-arg, or one without --urdf, is refused in one line."""
    with pytest.raises(InvalidArgument, match='name:=value'):
        parse_xacro_args(['reach=0.3'])
    assert parse_xacro_args(['reach:=0.3', 'a:=b:=c']) == {'reach': '0.3', 'a': 'b:=c'}
    with pytest.raises(SystemExit) as exit_:
        build_main(['--robot', 'ur5', '--xacro-arg', 'a:=1', '--out', 'x'])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and err.count('\n') == 1 and '--xacro-arg needs --urdf' in err
    with pytest.raises(InvalidModel, match='^xacro: <robot_description>: '):
        expand_xacro('<robot xmlns:xacro="http://www.ros.org/wiki/xacro"><xacro:nope/></robot>')


def test_package_uris_resolved(tmp_path):
    """package:// meshes found in a package folder become absolute paths; others stay."""
    mesh = tmp_path / 'pkgs' / 'arm_description' / 'meshes' / 'link.stl'
    mesh.parent.mkdir(parents=True)
    mesh.write_text('solid x\nendsolid x\n')
    urdf = ('<robot name="r"><link name="a"><collision><geometry>'
            '<mesh filename="package://arm_description/meshes/link.stl"/></geometry>'
            '</collision></link><link name="b"><visual><geometry>'
            '<mesh filename="package://other/m.stl"/></geometry></visual></link></robot>')
    out = resolve_package_uris(urdf, [str(tmp_path / 'nowhere'), str(tmp_path / 'pkgs')])
    assert f'filename="{mesh.resolve()}"' in out
    assert 'filename="package://other/m.stl"' in out


@pytest.mark.e2e
def test_sik_build_from_xacro(description, tmp_path):
    """sik-build --urdf arm.urdf.xacro --xacro-arg ...: a bundle of the expanded arm that loads."""
    from sik_ros import SelectiveIK
    out = tmp_path / 'bundles' / 'arm'
    # --time 17: about 6 s of training after the other stages' estimate (11 s; they take well
    # under 1 s before the training), over the 5 s below which a build refuses to start
    run = sik_build('--urdf', str(description), '--xacro-arg', 'reach:=0.35', '--out', str(out),
                    '--time', '17', '--rows', '4000', '--preset', 'tiny', '--check-targets', '5',
                    '--quiet')
    assert run.returncode == 0, run.stderr[-3000:]
    urdf = Path(str(out) + '.urdf')
    assert f'xacro: {description} -> {urdf}' in run.stdout
    manifest = json.loads((out / 'bundle.json').read_text())
    assert json.dumps(str(urdf.resolve())) in json.dumps(manifest)
    ik = SelectiveIK.load(out)
    assert ik.joint_names == ['turn_joint', 'upper_joint', 'fore_joint', 'wrist_joint']
    position, _ = ik.fk(np.zeros(4))
    np.testing.assert_allclose(position, [0.0, 0.0, 1.0], atol=1e-12)
