"""How far tip poses are from a goal, for poses already computed.

A path's waypoint errors and the evaluation compute position errors [m] and orientation errors
[rad] of tip poses they hold with :func:`goal_errors`; errors of configurations come from the
compiled kernels (:func:`sik_ros.solver.refine.errors`, the measure refinement reports). The two
agree to rounding.
"""

from typing import Optional, Tuple

import numpy as np

from sik_ros.kinematics.rotations import rotation_angle


def goal_errors(p: np.ndarray, r: Optional[np.ndarray], position: np.ndarray,
                rotation: Optional[np.ndarray] = None) -> Tuple[np.ndarray, np.ndarray]:
    """Position errors [m] and orientation errors [rad] of tip poses against a goal, (M,).

    Args:
        p: tip positions (M, 3) [m].
        r: tip rotations (M, 3, 3) (not read without ``rotation``).
        position: the goal position (3,), or one per row (M, 3) [m].
        rotation: the goal rotation (3, 3), or one per row (M, 3, 3); None for a position
            goal, whose orientation errors are 0.
    """
    perr = np.linalg.norm(p - position, axis=1)
    if rotation is None:
        return perr, np.zeros(len(p))
    return perr, rotation_angle(rotation, r)
