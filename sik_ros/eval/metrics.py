"""Measures of joint angles by forward kinematics: distance error, orientation, arm points.

Every error of the evaluation is recomputed from the joint angles with these, never taken from a
solver's own report, by Pinocchio's forward kinematics (:func:`pin_tips`), not the project's own
kernels that the solver uses.
"""

from typing import Sequence, Tuple

import numpy as np

from sik_ros.kinematics.chain import chain_forward
from sik_ros.kinematics.goal_error import goal_errors
from sik_ros.kinematics.robot import Robot


def arm_points(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Base origin, joint origins and tip of configurations (N, n) [rad]: (N, n + 2, 3) [m]."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    tip, _, origins, _ = chain_forward(robot.chain, q, frames=True)
    base = np.zeros((len(q), 1, 3))
    return np.concatenate([base, origins, tip[:, None]], axis=1)


def pin_tips(robot: Robot, q: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Tip positions (N, 3) [m] and rotations (N, 3, 3) of (N, n) [rad] by Pinocchio itself."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    pos, rot = np.empty((len(q), 3)), np.empty((len(q), 3, 3))
    for i, qi in enumerate(q):
        placement = robot.pin_placement(qi)
        pos[i], rot[i] = placement.translation, placement.rotation
    return pos, rot


def position_errors(robot: Robot, q: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Distance errors [m] of configurations (N, n) [rad] against targets (N, 3) or (3,) [m]."""
    p, _ = pin_tips(robot, q)
    return goal_errors(p, None, np.asarray(targets, dtype=float))[0]


def orientation_cosine(rot_target: np.ndarray, rot: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Cosine similarity and angle [rad] between a target rotation (3, 3) and rotations (N, 3, 3).

    The cosine similarity is the mean over the three axes (matrix columns) of the cosine between
    the target axis and the reached one, i.e. ``trace(R_t^T R) / 3 = (1 + 2 cos(angle)) / 3``.
    """
    cos_axes = np.einsum('ij,nij->nj', rot_target, rot)
    angle = np.arccos(np.clip((cos_axes.sum(axis=1) - 1) / 2, -1.0, 1.0))
    return cos_axes.mean(axis=1), angle


def mean_cm(errors: Sequence[float]) -> float:
    """Mean of errors [m] in cm (NaN when empty)."""
    errors = np.asarray(errors, dtype=float)
    return float(errors.mean() * 100) if errors.size else float('nan')
