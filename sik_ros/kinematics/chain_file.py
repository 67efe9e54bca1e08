"""Chain files: an arm's chain, limits, names and manifest in a few kB of JSON, without Pinocchio.

A chain file (``sik-chain``) carries what training needs of an arm to a machine that has torch
and NumPy but not Pinocchio, its URDF or example-robot-data (a GPU machine): the
:class:`~sik_ros.kinematics.chain.SerialChain` arrays, the joint limits and names and the
robot manifest that every artifact records. :class:`ChainArm` stands in for a
:class:`~sik_ros.kinematics.robot.Robot` where only those are used (the trainer, the data it
generates); a model trained on it carries the same robot manifest, so the tables, bundles and
the solver here take it as they take a model trained on the robot itself.

The file is written atomically and checked when read: its kind and version, every array's
shape and finiteness, rotations that are rotations, limits with ``lower < upper``, and a
SHA-256 of its content.
"""

from dataclasses import dataclass
import hashlib
import json
from pathlib import Path
from typing import Any, Dict, Mapping

import numpy as np

from sik_ros.artifacts import FORMAT_VERSION, read_json, robot_section, write_json_atomic
from sik_ros.errors import CorruptArtifact
from sik_ros.kinematics.chain import SerialChain
from sik_ros.kinematics.periodic import periodic_joints

#: ``kind`` of a chain file.
CHAIN_KIND = 'sik_chain'
#: The chain's arrays and their shapes (``n``: the number of joints).
CHAIN_ARRAYS = {'joint_rotations': ('n', 3, 3), 'joint_translations': ('n', 3),
                'axes': ('n', 3), 'base_rotation': (3, 3), 'base_translation': (3,),
                'tip_rotation': (3, 3), 'tip_translation': (3,)}
#: How far a stored rotation may be from orthonormal (rounding of the text form).
ROTATION_TOLERANCE = 1e-6


@dataclass(frozen=True)
class ChainArm:
    """An arm as a chain file gives it: what training uses of a robot, with no Pinocchio.

    Attributes:
        name: the robot's name.
        joint_names: the arm joints, in chain order.
        lower: joint lower limits (n,) [rad].
        upper: joint upper limits (n,) [rad].
        chain: the chain geometry.
        robot_manifest: the robot manifest of the robot it was exported from.
    """

    name: str
    joint_names: tuple
    lower: np.ndarray
    upper: np.ndarray
    chain: SerialChain
    robot_manifest: Mapping[str, Any]

    @property
    def dof(self) -> int:
        """Number of arm joints."""
        return len(self.joint_names)

    @property
    def periodic(self) -> np.ndarray:
        """(n,) bool: the joints whose range spans a turn."""
        return periodic_joints(self.lower, self.upper)

    def manifest(self) -> dict:
        """A copy of the robot's manifest, as a Robot gives it."""
        return json.loads(json.dumps(dict(self.robot_manifest)))


def chain_content(robot: Any) -> Dict:
    """The content of a robot's chain file (no checksum): its manifest and chain arrays."""
    chain = robot.chain
    return {'kind': CHAIN_KIND, 'format_version': FORMAT_VERSION, 'robot': robot.manifest(),
            'chain': {name: np.asarray(getattr(chain, name), dtype=float).tolist()
                      for name in CHAIN_ARRAYS}}


def content_sha256(content: Mapping) -> str:
    """SHA-256 of a chain file's content (every key but the checksum), canonical JSON."""
    body = {k: v for k, v in content.items() if k != 'sha256'}
    text = json.dumps(body, sort_keys=True, separators=(',', ':'))
    return hashlib.sha256(text.encode()).hexdigest()


def write_chain_file(robot: Any, path: Path) -> Path:
    """Write a robot's (or a :class:`ChainArm`'s) chain file atomically to ``path``."""
    content = chain_content(robot)
    content['sha256'] = content_sha256(content)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(path, content)
    return path


def load_chain_file(path: Path) -> ChainArm:
    """Read and check a chain file.

    Raises:
        CorruptArtifact: missing, unreadable, of another kind or version, altered (checksum),
            or with arrays or limits that do not make an arm (naming the part).
    """
    path = Path(path)
    content = read_json(path, f'chain file {path}')
    what = f'chain file {path}'
    if not isinstance(content, dict) or content.get('kind') != CHAIN_KIND:
        raise CorruptArtifact(f'{what} is not a sik_ros chain file (sik-chain writes them)')
    if content.get('format_version') != FORMAT_VERSION:
        raise CorruptArtifact(f'{what}: format version {content.get("format_version")!r}, '
                              f'this sik_ros reads {FORMAT_VERSION}')
    if content.get('sha256') != content_sha256(content):
        raise CorruptArtifact(f'{what}: its content does not match its sha256 (altered or '
                              f'damaged; export it again with sik-chain)')
    return chain_arm(content, what)


def chain_arm(content: Mapping, what: str = 'chain file') -> ChainArm:
    """A :class:`ChainArm` from a chain file's content, checked.

    Raises:
        CorruptArtifact: naming the part that does not make an arm.
    """
    robot = robot_section(content, what)
    names = robot.get('joint_names')
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        raise CorruptArtifact(f'{what}: robot.joint_names must be a list of joint names')
    n = len(names)
    lower, upper = (_array(robot.get(k), (n,), f'{what}: robot.{k}') for k in ('lower', 'upper'))
    if not np.all(lower < upper):
        raise CorruptArtifact(f'{what}: every joint needs lower < upper')
    arrays = content.get('chain')
    if not isinstance(arrays, dict):
        raise CorruptArtifact(f'{what}: "chain" must hold the chain arrays')
    chain = {}
    for name, shape in CHAIN_ARRAYS.items():
        shape = tuple(n if s == 'n' else s for s in shape)
        chain[name] = _array(arrays.get(name), shape, f'{what}: chain.{name}')
    rotations = np.concatenate([chain['joint_rotations'], chain['base_rotation'][None],
                                chain['tip_rotation'][None]])
    gram = rotations @ rotations.transpose(0, 2, 1)
    if (np.abs(gram - np.eye(3)).max() > ROTATION_TOLERANCE
            or np.abs(np.linalg.det(rotations) - 1).max() > ROTATION_TOLERANCE):
        raise CorruptArtifact(f'{what}: a rotation of the chain is not a rotation matrix')
    return ChainArm(robot['robot'], tuple(names), lower, upper, SerialChain(**chain), robot)


def _array(value: Any, shape: tuple, what: str) -> np.ndarray:
    """A finite float array of ``shape`` from JSON lists, or :class:`CorruptArtifact`."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise CorruptArtifact(f'{what} must be numbers of shape {shape}') from exc
    if arr.shape != shape or not np.all(np.isfinite(arr)):
        raise CorruptArtifact(f'{what} must be finite numbers of shape {shape}; got shape '
                              f'{arr.shape}')
    return arr
