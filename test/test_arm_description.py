"""An arm from robot_description: checks, cache keys and entries, the table that answers first."""

import json
import os
from pathlib import Path

import numpy as np
import pytest

from arm_urdfs import chain_text, erd_share, erd_text, two_arm_text
from sik_ros.bundles.cache import ArmEntry, verify_checksums, write_checksums
from sik_ros.bundles.sweep_models import sweep_models
from sik_ros.errors import CorruptArtifact, ModelNotReady, SikError
from sik_ros.kinematics.arm_description import (chain_key, MAX_CHAIN_JOINTS,
                                                MAX_DESCRIPTION_BYTES)
from sik_ros.serving.arm_source import first_solver, prepare_arm
from sik_ros.solver import SelectiveIK, SolverConfig


def files_under(folder: Path):
    """Every file under a folder (none when it does not exist)."""
    return sorted(p for p in Path(folder).rglob('*') if p.is_file())


def reached(robot, q, position, quat=None):
    """Position [m] and orientation [rad] errors of ``q`` by Pinocchio's own FK."""
    placement = robot.pin_placement(q)
    perr = float(np.linalg.norm(placement.translation - position))
    if quat is None:
        return perr, 0.0
    x, y, z, w = quat
    import pinocchio as pin
    target = pin.Quaternion(w, x, y, z).toRotationMatrix()
    rerr = float(np.linalg.norm(pin.log3(target.T @ placement.rotation)))
    return perr, rerr


BAD = {
    'empty': ('', 'base_link', 'tool0', 'empty'),
    'malformed': ('<robot name="a"><link name="x">', 'base_link', 'tool0', 'not a URDF'),
    'not a urdf': ('<html><body/></html>', 'base_link', 'tool0', 'not a URDF'),
    'unknown base': (None, 'no_such_link', 'tool0', "base_frame 'no_such_link' is not in"),
    'unknown tip': (None, 'base_link', 'no_such_tip', "tip_frame 'no_such_tip' is not in"),
    'tip above base': (None, 'tool0', 'base_link', 'is not below base frame'),
    'no movable joint': (None, 'wrist_3_link', 'tool0', 'no revolute joint moves'),
    'prismatic': (chain_text(3, kind='prismatic'), 'base', 'tip', 'prismatic'),
    f'{MAX_CHAIN_JOINTS + 24} joints': (chain_text(MAX_CHAIN_JOINTS + 24), 'base', 'tip',
                                        f'has {MAX_CHAIN_JOINTS + 24} joints'),
    'too large': ('<robot name="a">' + ' ' * (MAX_DESCRIPTION_BYTES + 1) + '</robot>', 'base',
                  'tip', 'over the'),
}


@pytest.mark.parametrize('case', sorted(BAD))
def test_bad_descriptions_are_refused_and_write_nothing(case, tmp_path):
    """Each bad description or chain raises a SikError naming it; the cache stays empty."""
    text, base, tip, words = BAD[case]
    text = erd_text('ur5') if text is None else text
    with pytest.raises(SikError) as err:
        prepare_arm(text, base, tip, str(tmp_path))
    assert words in str(err.value), str(err.value)
    assert '\n' not in str(err.value)
    assert files_under(tmp_path) == []


def test_chain_key_follows_the_chain_only(tmp_path):
    """Same chain in another description: same key; a changed limit or a moved joint: another."""
    ur5 = erd_text('ur5')
    a = prepare_arm(ur5, 'base_link', 'tool0', str(tmp_path))
    # a comment and a link elsewhere in the tree change nothing of the chain
    extra = ur5.replace('</robot>', '<!-- mounted on cell 3 --><link name="camera"/>'
                        '<joint name="cam" type="fixed"><parent link="base_link"/>'
                        '<child link="camera"/></joint></robot>')
    b = prepare_arm(extra, 'base_link', 'tool0', str(tmp_path))
    assert a.key == b.key and a.entry.path == b.entry.path
    lower = ur5.replace('lower="-6.28318530718"', 'lower="-3.0"', 1)
    assert lower != ur5
    assert prepare_arm(lower, 'base_link', 'tool0', str(tmp_path)).key != a.key
    moved = ur5.replace('xyz="0.0 0.0 0.089159"', 'xyz="0.0 0.0 0.1"', 1)
    assert moved != ur5
    assert prepare_arm(moved, 'base_link', 'tool0', str(tmp_path)).key != a.key
    # the entry's URDF is kept (written once), and its robot is the chain asked for
    assert a.entry.urdf.is_file() and a.robot.joint_names == b.robot.joint_names
    assert chain_key(b.robot) == a.key


def test_one_arm_of_a_two_arm_tree(tmp_path):
    """Each arm of a tree is its own chain (the other arm and the torso joint locked)."""
    text = two_arm_text()
    left = prepare_arm(text, 'left_base_link', 'left_tool0', str(tmp_path))
    right = prepare_arm(text, 'right_base_link', 'right_tool0', str(tmp_path))
    assert left.robot.joint_names == [f'left_{n}' for n in (
        'shoulder_pan_joint', 'shoulder_lift_joint', 'elbow_joint', 'wrist_1_joint',
        'wrist_2_joint', 'wrist_3_joint')]
    assert right.robot.joint_names[0] == 'right_shoulder_pan_joint'
    assert left.key != right.key


def test_meshes_resolve_where_their_package_is_found(tmp_path, monkeypatch):
    """Collision meshes found on ROS_PACKAGE_PATH are used; without it they are left out, said."""
    monkeypatch.delenv('ROS_PACKAGE_PATH', raising=False)
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path / 'none'))
    bare = prepare_arm(erd_text('ur5'), 'base_link', 'tool0', str(tmp_path / 'a'))
    assert len(bare.missing_meshes) >= 6
    monkeypatch.setenv('ROS_PACKAGE_PATH', erd_share())
    full = prepare_arm(erd_text('ur5'), 'base_link', 'tool0', str(tmp_path / 'b'))
    assert full.missing_meshes == []
    # the shapes stay (the UR5's end box); the meshes not found are the parts left out
    assert bare.robot.collision_model.ngeoms == \
        full.robot.collision_model.ngeoms - len(bare.missing_meshes) >= 1
    assert full.key != bare.key  # collision geometry is part of what defines the chain


@pytest.mark.parametrize('name, base, tip', [('ur5', 'base_link', 'tool0'),
                                             ('panda', 'panda_link0', 'panda_hand_tcp')])
def test_table_of_configurations_answers_exactly(name, base, tip, tmp_path):
    """With no learned model, position and pose goals get distinct solutions exact by Pinocchio."""
    arm = prepare_arm(erd_text(name), base, tip, str(tmp_path))
    ik, learned = first_solver(arm, SolverConfig(), seconds=1.0, say=lambda _: None)
    assert not learned and not ik.learned
    rng = np.random.default_rng(3)
    q = rng.uniform(arm.robot.lower, arm.robot.upper, (10, arm.robot.dof))
    checked = 0
    for qi in q:
        p, quat = ik.fk(qi)
        for orientation in (None, quat):
            res = ik.solve(p, orientation, num_solutions=8)
            assert res.success
            exact = [s for s in res.solutions if s.converged]
            assert len(exact) >= 2
            for s in exact:
                perr, rerr = reached(arm.robot, s.q, p, orientation)
                assert perr <= 1e-4 and rerr <= 1e-3
                assert np.all(s.q >= arm.robot.lower - 1e-12)
                assert np.all(s.q <= arm.robot.upper + 1e-12)
                checked += 1
    assert checked >= 40


def test_raw_answers_wait_for_the_learned_model(tmp_path):
    """refine=False with no learned model raises ModelNotReady (the node's MODEL_NOT_READY)."""
    arm = prepare_arm(erd_text('ur5'), 'base_link', 'tool0', str(tmp_path))
    ik = SelectiveIK(arm.robot, sweep_models(arm.robot, rows=20_000))
    p, _ = ik.fk(np.zeros(6))
    with pytest.raises(ModelNotReady, match='raw answers'):
        ik.solve(p, refine=False)


def test_checksums_find_a_damaged_or_unfinished_bundle(tmp_path):
    """A changed, missing or unlisted-checksum bundle is refused; a damaged entry is set aside."""
    entry = ArmEntry(tmp_path, 'k')
    entry.bundle.mkdir(parents=True)
    (entry.bundle / 'bundle.json').write_text('{}')
    (entry.bundle / 'sik_pose.pt').write_bytes(b'weights')
    assert entry.checked_bundle() is None  # unfinished: left alone
    assert entry.bundle.is_dir()
    write_checksums(entry.bundle)
    verify_checksums(entry.bundle)
    assert entry.checked_bundle() == entry.bundle
    (entry.bundle / 'sik_pose.pt').write_bytes(b'weightz')
    with pytest.raises(CorruptArtifact, match='changed'):
        verify_checksums(entry.bundle)
    assert entry.checked_bundle() is None
    assert not entry.bundle.exists()
    aside = [p for p in entry.path.iterdir() if p.name.startswith('bundle.damaged-')]
    assert len(aside) == 2  # the folder and its reason
    record = json.loads((aside[0] if aside[0].is_dir() else aside[1]).joinpath(
        'checksums.json').read_text())
    assert set(record['files']) == {'bundle.json', 'sik_pose.pt'}


def test_one_builder_per_entry(tmp_path):
    """The entry's build lock is held by one holder at a time (another process waits)."""
    a, b = ArmEntry(tmp_path, 'k'), ArmEntry(tmp_path, 'k')
    with a.building() as first:
        assert first
        pid = os.fork()
        if pid == 0:  # another process: refused while held
            with b.building() as second:
                os._exit(0 if not second else 1)
        _, status = os.waitpid(pid, 0)
        assert os.WEXITSTATUS(status) == 0
    with b.building() as again:
        assert again


def test_the_learned_model_replaces_the_table_only_when_not_worse(tmp_path):
    """The verdict: not worse in success and distinct solutions; kept per bundle checksum."""
    from sik_ros.serving.arm_source import (keep_verdict, learned_not_worse, table_preferred)

    def figures(success, distinct):
        return {'table': {'pose': {'success': 1.0, 'distinct_median': 16.0}},
                'learned': {'pose': {'success': success, 'distinct_median': distinct}}}

    assert learned_not_worse(figures(1.0, 16.0))
    assert not learned_not_worse(figures(0.98, 16.0))
    assert not learned_not_worse(figures(1.0, 9.0))
    arm = prepare_arm(erd_text('ur5'), 'base_link', 'tool0', str(tmp_path))
    arm.entry.bundle.mkdir(parents=True)
    (arm.entry.bundle / 'bundle.json').write_text('{}')
    write_checksums(arm.entry.bundle)
    assert not table_preferred(arm)  # no verdict: a bundle dropped in is served
    assert keep_verdict(arm, figures(1.0, 9.0)) is False
    assert table_preferred(arm)
    (arm.entry.bundle / 'bundle.json').write_text('{"rebuilt": 1}')
    write_checksums(arm.entry.bundle)
    assert not table_preferred(arm)  # the verdict was another bundle's
