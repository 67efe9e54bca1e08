"""sik_ros: Selective Inverse Kinematics (learned multi-solution IK) for ROS 2.

The library needs no ROS: ``SelectiveIK.load("panda").solve(position)`` gives ranked joint
solutions. The ROS layer (the node, message conversions, a client and the demo) lives in
:mod:`sik_ros.ros`; the public contract is docs/interfaces.md.
"""

__version__ = '0.2.0'

from sik_ros.collision import Obstacle  # noqa: E402
from sik_ros.errors import (  # noqa: E402
    ArtifactError, ArtifactExists, ArtifactMismatch, CorruptArtifact, FrameNotFound,
    InvalidArgument, InvalidGoal, InvalidModel, InvalidSeed, JointLimitViolation,
    RobotNotFound, SikError, TrainingDiverged)
from sik_ros.kinematics import Robot
from sik_ros.robots import load_robot  # noqa: E402
from sik_ros.solver import IKResult, SelectiveIK, Solution, SolverConfig  # noqa: E402

__all__ = [
    'ArtifactError', 'ArtifactExists', 'ArtifactMismatch', 'CorruptArtifact', 'FrameNotFound',
    'IKResult', 'InvalidArgument', 'InvalidGoal', 'InvalidModel', 'InvalidSeed',
    'JointLimitViolation', 'Obstacle', 'Robot', 'RobotNotFound', 'SelectiveIK', 'SikError',
    'Solution', 'SolverConfig', 'TrainingDiverged', 'load_robot',
]
