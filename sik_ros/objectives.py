"""The ranking objectives, importable from the package's top level as before 0.4.0.

They live in :mod:`sik_ros.solver.objectives`; this module and ``from sik_ros import
JointLimitMargin`` (and the others) name the same classes.
"""

from sik_ros.solver.objectives import (ElbowHeight, FromFunction, JointLimitMargin,
                                       Manipulability, Objective, ObstacleClearance,
                                       SeedDistance, Sum, Weighted)

__all__ = ['ElbowHeight', 'FromFunction', 'JointLimitMargin', 'Manipulability', 'Objective',
           'ObstacleClearance', 'SeedDistance', 'Sum', 'Weighted']
