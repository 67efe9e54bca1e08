"""URDF texts for the tests of arms from robot_description: example-robot-data, trees, bad ones."""

from pathlib import Path
import re

import example_robot_data as erd


def erd_text(name: str) -> str:
    """The URDF text of an example-robot-data robot."""
    return Path(erd.load(name).urdf).read_text()


def erd_share() -> str:
    """The folder holding example-robot-data's package (its meshes' ``package://`` root)."""
    return str(Path(erd.load('ur5').urdf).resolve().parents[4])


def chain_text(joints: int, name: str = 'snake', kind: str = 'revolute') -> str:
    """A serial chain of ``joints`` joints of ``kind`` from ``base`` to ``tip`` (box links)."""
    links = ['<link name="base"/>'] + [
        f'<link name="l{i}"><collision><geometry><box size="0.04 0.04 0.1"/></geometry>'
        f'</collision></link>' for i in range(joints)] + ['<link name="tip"/>']
    parts = []
    parent = 'base'
    for i in range(joints):
        axis = ('0 0 1', '0 1 0')[i % 2]
        parts.append(f'<joint name="j{i}" type="{kind}"><parent link="{parent}"/>'
                     f'<child link="l{i}"/><origin xyz="0 0 0.1"/><axis xyz="{axis}"/>'
                     f'<limit lower="-2.5" upper="2.5" effort="1" velocity="1"/></joint>')
        parent = f'l{i}'
    parts.append(f'<joint name="tip_joint" type="fixed"><parent link="{parent}"/>'
                 f'<child link="tip"/><origin xyz="0 0 0.05"/></joint>')
    return f'<robot name="{name}">' + ''.join(links + parts) + '</robot>'


def two_arm_text() -> str:
    """Two UR5 arms on one torso (prefixed ``left_`` and ``right_``), as one description."""
    ur5 = erd_text('ur5')
    body = ur5[ur5.index('>', ur5.index('<robot')) + 1:ur5.rindex('</robot>')]
    body = re.sub(r'<\?xml[^>]*\?>', '', body)

    def prefixed(prefix: str) -> str:
        text = re.sub(r'(link|joint|parent link|child link)="', rf'\1="{prefix}', body)
        text = re.sub(r'<(link|joint) name="', rf'<\1 name="{prefix}', text)
        return text.replace(f'name="{prefix}{prefix}', f'name="{prefix}')

    left, right = prefixed('left_'), prefixed('right_')
    mounts = ''.join(
        f'<joint name="{side}_mount" type="fixed"><parent link="torso"/>'
        f'<child link="{side}_world"/><origin xyz="0 {y} 0.5" rpy="{r} 0 0"/></joint>'
        for side, y, r in (('left', 0.3, -0.6), ('right', -0.3, 0.6)))
    return ('<robot name="two_arms"><link name="world"/><link name="torso"/>'
            '<joint name="torso_yaw" type="revolute"><parent link="world"/><child link="torso"/>'
            '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
            + mounts + left + right + '</robot>')
