"""sik_ros: Selective Inverse Kinematics (learned multi-solution IK) for ROS 2.

The library needs no ROS: ``SelectiveIK.load("panda").solve(position)`` gives ranked joint
solutions. The ROS layer (the node, message conversions, a client and the demo) lives in
:mod:`sik_ros.ros`; the public contract is docs/interfaces.md.

The public names below are loaded on first use (PEP 562), so that importing a light module
(``sik_ros.errors``, a CLI's ``--help``, the ROS client) does not load torch or Pinocchio.
"""

from sik_ros._lazy import lazy_exports

__version__ = '0.9.0'

#: Where each public name lives.
_EXPORTS = {
    'ArtifactError': 'sik_ros.errors', 'ArtifactExists': 'sik_ros.errors',
    'ArtifactMismatch': 'sik_ros.errors', 'CorruptArtifact': 'sik_ros.errors',
    'FrameNotFound': 'sik_ros.errors', 'IKResult': 'sik_ros.solver.results',
    'InvalidArgument': 'sik_ros.errors', 'InvalidGoal': 'sik_ros.errors',
    'InvalidModel': 'sik_ros.errors', 'InvalidSeed': 'sik_ros.errors',
    'JointLimitViolation': 'sik_ros.errors', 'Obstacle': 'sik_ros.kinematics.collision',
    'Robot': 'sik_ros.kinematics.robot', 'RobotNotFound': 'sik_ros.errors',
    'SelectiveIK': 'sik_ros.solver.selective_ik', 'SikError': 'sik_ros.errors',
    'Solution': 'sik_ros.solver.results', 'SolverConfig': 'sik_ros.solver.config',
    'TrainingDiverged': 'sik_ros.errors', 'load_robot': 'sik_ros.kinematics.robots',
    # the ranking objectives (sik_ros.objectives, as before 0.4.0)
    'ElbowHeight': 'sik_ros.solver.objectives', 'FromFunction': 'sik_ros.solver.objectives',
    'JointLimitMargin': 'sik_ros.solver.objectives',
    'Manipulability': 'sik_ros.solver.objectives', 'Objective': 'sik_ros.solver.objectives',
    'ObstacleClearance': 'sik_ros.solver.objectives',
    'SeedDistance': 'sik_ros.solver.objectives', 'Sum': 'sik_ros.solver.objectives',
    'Weighted': 'sik_ros.solver.objectives',
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, globals(), _EXPORTS)
