"""What the solver's stages share: the goal of a call and the context of a solver instance."""

from dataclasses import dataclass
from typing import Dict, Optional

import numpy as np
import pinocchio as pin

from sik_ros.bundles.bundle import GoalModel
from sik_ros.kinematics.collision import CollisionChecker
from sik_ros.kinematics.robot import Robot
from sik_ros.kinematics.rotations import matrix_quaternion
from sik_ros.solver.config import SolverConfig

POSITION, POSE = 'position', 'pose'


@dataclass(frozen=True)
class Goal:
    """One target.

    Attributes:
        position: tip position in the base frame (3,) [m].
        rotation: tip orientation (3, 3), or None for a position goal.
        given_quaternion: the orientation as the caller gave it (unit, x y z w), when known.
    """

    position: np.ndarray
    rotation: Optional[np.ndarray] = None
    given_quaternion: Optional[np.ndarray] = None

    @property
    def kind(self) -> str:
        """``position`` or ``pose``."""
        return POSITION if self.rotation is None else POSE

    @property
    def quaternion(self) -> np.ndarray:
        """The orientation as a unit quaternion x y z w with w >= 0 (pose goals only).

        The caller's own when it gave one (converting the matrix back is not free).
        """
        quat = self.given_quaternion
        if quat is None:
            quat = matrix_quaternion(self.rotation)
        return -quat if quat[3] < 0 else quat


@dataclass(frozen=True)
class Context:
    """A solver instance's parts, handed to every stage.

    Attributes:
        robot: the arm.
        models: the network, configs and table per goal kind.
        config: the solver's settings.
        data: Pinocchio data of this instance (not thread-safe: one per thread).
        checker: collision checker of this instance (not thread-safe either).
    """

    robot: Robot
    models: Dict[str, GoalModel]
    config: SolverConfig
    data: pin.Data
    checker: CollisionChecker

    def ignores_last(self, kind: str) -> bool:
        """Whether postures of a ``kind`` goal are compared without the last joint.

        For position goals, when the tip lies on the last joint's axis: that joint only turns
        the tool about it, so it tells no postures apart.
        """
        return kind == POSITION and tip_on_last_axis(self.robot)


def tip_on_last_axis(robot: Robot) -> bool:
    """Whether the tip lies on the last joint's axis (the last joint does not move it)."""
    return bool(np.linalg.norm(robot.chain.tip_translation[:2]) < 1e-9)
