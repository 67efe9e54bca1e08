"""The links of a robot description seen from its served chain.

Each link is fixed to the base, fixed to the tip, moved by the chain's joints, or none of these.
A request may name a link other than the base and tip frames: a goal in a frame bolted to the
base (``world``, a table link), a pose for a link bolted to the tool (the flange rather than the
tool centre point), the poses of the links along the arm. :class:`LinkFrames` tells which links
the chain's joints alone place (their pose follows from the arm's joint values, whatever the
other joints of the description are) and computes their poses with Pinocchio.

A link moved by a joint that is not in the chain (a finger, another limb) is not among them.
"""

from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
import pinocchio as pin

from sik_ros.kinematics.model_tree import chain_path, find_frame
from sik_ros.kinematics.robot import Robot


@dataclass(frozen=True)
class Transform:
    """A rigid transform: ``x_parent = rotation @ x_child + translation``.

    Attributes:
        rotation: (3, 3) rotation matrix.
        translation: (3,) translation [m].
    """

    rotation: np.ndarray
    translation: np.ndarray

    @classmethod
    def of(cls, placement: pin.SE3) -> 'Transform':
        """A Pinocchio placement as a :class:`Transform` (copied)."""
        return cls(np.array(placement.rotation), np.array(placement.translation))

    def inverse(self) -> 'Transform':
        """The inverse transform."""
        return Transform(self.rotation.T, -self.rotation.T @ self.translation)

    def __matmul__(self, other: 'Transform') -> 'Transform':
        """The composition ``self`` after ``other``."""
        return Transform(self.rotation @ other.rotation,
                         self.rotation @ other.translation + self.translation)

    @property
    def is_identity(self) -> bool:
        """Whether it is the identity (to 1e-12)."""
        return bool(np.allclose(self.rotation, np.eye(3), rtol=0, atol=1e-12)
                    and np.allclose(self.translation, 0.0, rtol=0, atol=1e-12))


IDENTITY = Transform(np.eye(3), np.zeros(3))


class LinkFrames:
    """Which links of the description the chain places, and where.

    Attributes:
        base_fixed: links rigidly attached to the base frame (the base itself included).
        tip_fixed: links rigidly attached to the tip frame (the tip itself included).
        moving: links placed by the chain's joints, base to tip order of their joints (the
            tip-fixed ones included); with ``base_fixed``, every link whose pose
            :meth:`poses` computes.
    """

    def __init__(self, robot: Robot):
        """Classify the links of ``robot``'s description and precompute the fixed offsets."""
        full = robot.full_model
        self._robot = robot
        path = chain_path(full, robot.base_frame, robot.tip_frame)
        base_joint = full.frames[find_frame(full, robot.base_frame)].parentJoint
        order = {j: k for k, j in enumerate(path)}
        links = {f.name for f in full.frames if f.type == pin.FrameType.BODY}
        links |= {robot.base_frame, robot.tip_frame}
        data = full.createData()
        pin.framesForwardKinematics(full, data, pin.neutral(full))
        base = Transform.of(data.oMf[find_frame(full, robot.base_frame)])
        tip = Transform.of(data.oMf[find_frame(full, robot.tip_frame)])
        self._in_base: Dict[str, Transform] = {}
        self._from_tip: Dict[str, Transform] = {}
        moving: List[Tuple[int, str]] = []
        for name in sorted(links):
            frame = full.frames[find_frame(full, name)]
            placed = Transform.of(data.oMf[find_frame(full, name)])
            if frame.parentJoint == base_joint:
                self._in_base[name] = base.inverse() @ placed
            elif frame.parentJoint in order:
                moving.append((order[frame.parentJoint], name))
                if frame.parentJoint == path[-1]:
                    self._from_tip[name] = tip.inverse() @ placed
        self.base_fixed: List[str] = sorted(self._in_base)
        self.tip_fixed: List[str] = sorted(self._from_tip)
        self.moving: List[str] = [name for _, name in sorted(moving)]
        self._reduced_ids = {name: find_frame(robot.model, name) for name in self.moving}
        self._base_id = find_frame(robot.model, robot.base_frame)

    def in_base(self, link: str) -> Optional[Transform]:
        """The pose of a base-fixed link in the base frame; None for any other link.

        ``''`` and ``'/'``-prefixed names are taken as ROS frame ids: ``''`` is the base.
        """
        name = link.lstrip('/') or self._robot.base_frame
        return self._in_base.get(name)

    def from_tip(self, link: str) -> Optional[Transform]:
        """The pose of a tip-fixed link in the tip frame; None for any other link (``''``: tip)."""
        name = link.lstrip('/') or self._robot.tip_frame
        return self._from_tip.get(name)

    def placeable(self, link: str) -> bool:
        """Whether :meth:`poses` can place ``link``."""
        return link in self._in_base or link in self._reduced_ids

    def poses(self, q: np.ndarray, links: Sequence[str]) -> List[Transform]:
        """Poses of ``links`` in the base frame for arm joint values ``q`` (n,) [rad].

        Raises:
            KeyError: a link :meth:`placeable` refuses.
        """
        moving = [name for name in links if name not in self._in_base]
        placed: Dict[str, Transform] = {}
        if moving:
            model = self._robot.model
            data = model.createData()
            pin.framesForwardKinematics(model, data, np.asarray(q, dtype=float))
            base = Transform.of(data.oMf[self._base_id]).inverse()
            for name in moving:
                placed[name] = base @ Transform.of(data.oMf[self._reduced_ids[name]])
        return [self._in_base[name] if name in self._in_base else placed[name]
                for name in links]
