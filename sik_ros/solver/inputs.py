"""Checks of what a caller hands the solver: goals, solution counts, seeds.

Every problem raises a :class:`~sik_ros.errors.SikError` subclass naming the field.
"""

from typing import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from sik_ros.errors import InvalidArgument, InvalidGoal, InvalidSeed, JointLimitViolation
from sik_ros.kinematics import Robot
from sik_ros.solver.context import Goal


def check_goal(position, orientation, goals: Sequence[str]) -> Goal:
    """A :class:`Goal` from a position (3,) [m] and an optional quaternion (x, y, z, w).

    Raises:
        InvalidGoal: not 3 finite numbers, not a finite non-zero quaternion, or a goal kind
            the bundle has no model for (``goals``).
    """
    try:
        pos = np.asarray(position, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidGoal(f'position must be 3 numbers; got {position!r}') from exc
    if pos.shape != (3,):
        raise InvalidGoal(f'position must have 3 elements; got shape {pos.shape}')
    if not np.all(np.isfinite(pos)):
        raise InvalidGoal(f'position must be finite; got {pos.tolist()}')
    rot = None
    if orientation is not None:
        try:
            quat = np.asarray(orientation, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InvalidGoal(f'orientation must be a quaternion; got {orientation!r}') from exc
        if quat.shape != (4,):
            raise InvalidGoal(f'orientation must be a quaternion (x, y, z, w); got shape '
                              f'{quat.shape}')
        if not np.all(np.isfinite(quat)):
            raise InvalidGoal(f'orientation must be finite; got {quat.tolist()}')
        norm = np.linalg.norm(quat)
        if norm < 1e-9:
            raise InvalidGoal('orientation quaternion is zero')
        rot = Rotation.from_quat(quat / norm).as_matrix()
    goal = Goal(pos, rot)
    if goal.kind not in goals:
        raise InvalidGoal(f'this bundle has no model for {goal.kind} goals (it has '
                          f'{sorted(goals)})')
    return goal


def check_num_solutions(num_solutions, cap: int) -> int:
    """``num_solutions`` as an int in 1..``cap``, or :class:`InvalidArgument`."""
    if isinstance(num_solutions, bool) or not isinstance(num_solutions, (int, np.integer)):
        raise InvalidArgument(f'num_solutions must be an integer; got {num_solutions!r}')
    if not 1 <= num_solutions <= cap:
        raise InvalidArgument(f'num_solutions must be between 1 and {cap}; got '
                              f'{num_solutions}')
    return int(num_solutions)


def check_seed(robot: Robot, seed) -> np.ndarray:
    """A seed as a (n,) array within the limits, or :class:`InvalidSeed` saying what is wrong."""
    try:
        q = np.asarray(seed, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidSeed(f'seed must be {robot.dof} numbers; got {seed!r}') from exc
    if q.shape != (robot.dof,):
        raise InvalidSeed(f'seed must have {robot.dof} joint values '
                          f'({", ".join(robot.joint_names)}); got shape {q.shape}')
    if not np.all(np.isfinite(q)):
        raise InvalidSeed(f'seed must be finite; got {q.tolist()}')
    eps = 1e-6
    for name, v, lo, hi in zip(robot.joint_names, q, robot.lower, robot.upper):
        if v < lo - eps or v > hi + eps:
            raise JointLimitViolation(name, float(v), float(lo), float(hi))
    return np.clip(q, robot.lower, robot.upper)
