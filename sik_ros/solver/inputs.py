"""Checks of what a caller hands the solver: goals, solution counts, seeds.

Every problem raises a :class:`~sik_ros.errors.SikError` subclass naming the field.
"""

from typing import List, Optional, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from sik_ros.errors import InvalidArgument, InvalidGoal, InvalidSeed, JointLimitViolation
from sik_ros.kinematics.collision import Obstacle
from sik_ros.kinematics.robot import Robot
from sik_ros.kinematics.rotations import quaternion_matrix
from sik_ros.solver.context import Goal
from sik_ros.validation import MAX_DISTANCE, quaternion, real_array, vector


def check_goal(position, orientation, goals: Sequence[str]) -> Goal:
    """A :class:`Goal` from a position (3,) [m] and an optional quaternion (x, y, z, w).

    Raises:
        InvalidGoal: not 3 finite numbers, not a finite non-zero quaternion, or a goal kind
            the bundle has no model for (``goals``).
    """
    pos = vector(position, 3, 'position', InvalidGoal, limit=MAX_DISTANCE)
    rot = quat = None
    if orientation is not None:
        quat = quaternion(orientation, 'orientation', InvalidGoal)
        rot = quaternion_matrix(quat)
    goal = Goal(pos, rot, quat)
    if goal.kind not in goals:
        raise InvalidGoal(f'this bundle has no model for {goal.kind} goals (it has '
                          f'{sorted(goals)})')
    return goal


def check_arrays(positions, orientations, min_rows: int = 0):
    """Positions (N, 3) and None or quaternions (N, 4) as float arrays, N >= ``min_rows``.

    Raises:
        InvalidGoal: not arrays of those shapes.
    """
    pos = real_array(positions, 'positions', InvalidGoal, 'an (N, 3) array')
    if pos.ndim != 2 or pos.shape[1] != 3 or len(pos) < min_rows:
        raise InvalidGoal(f'positions must be an (N, 3) array with N >= {min_rows}; got shape '
                          f'{pos.shape}')
    quat = None
    if orientations is not None:
        quat = real_array(orientations, 'orientations', InvalidGoal, 'an (N, 4) array')
        if quat.shape != (len(pos), 4):
            raise InvalidGoal(f'orientations must have shape ({len(pos)}, 4) like the '
                              f'positions; got {quat.shape}')
    return pos, quat


def check_path(positions, orientations, goals: Sequence[str],
               max_waypoints: Optional[int] = None) -> List[Goal]:
    """Waypoints: (N, 3) positions [m] and None or (N, 4) quaternions, as :class:`Goal` s.

    Raises:
        InvalidGoal: no waypoints, more than ``max_waypoints``, mismatched lengths, or a bad
            waypoint (naming it).
    """
    pos, quat = check_arrays(positions, orientations, min_rows=1)
    if max_waypoints is not None and len(pos) > max_waypoints:
        raise InvalidGoal(f'{len(pos)} waypoints; at most {max_waypoints} are accepted '
                          f'(SolverConfig.max_waypoints)')
    kind = 'position' if quat is None else 'pose'
    fine = kind in goals and np.isfinite(pos).all() and (np.abs(pos) <= MAX_DISTANCE).all()
    if fine and quat is not None:
        scale = np.abs(quat).max(axis=1)
        fine = bool(np.isfinite(quat).all() and (scale >= 1e-150).all())
    if fine:  # every waypoint good: checked and converted at once
        if quat is None:
            return [Goal(p) for p in pos.copy()]
        unit = quat / scale[:, None]  # normalised row by row as quaternion() does it
        unit = np.array([u / np.linalg.norm(u) for u in unit])
        rot = Rotation.from_quat(unit).as_matrix()
        return [Goal(p, r, u) for p, r, u in zip(pos.copy(), rot, unit)]
    for i, p in enumerate(pos):  # one is bad: name it, as check_goal says it
        try:
            check_goal(p, None if quat is None else quat[i], goals)
        except InvalidGoal as exc:
            raise InvalidGoal(f'waypoint {i}: {exc}') from exc
    raise AssertionError('a waypoint failed the batch check but passed check_goal')


def check_num_solutions(num_solutions, cap: int, what: str = 'num_solutions') -> int:
    """``num_solutions`` as an int in 1..``cap``, or :class:`InvalidArgument` naming ``what``."""
    if isinstance(num_solutions, bool) or not isinstance(num_solutions, (int, np.integer)):
        raise InvalidArgument(f'{what} must be an integer; got {num_solutions!r}')
    if not 1 <= num_solutions <= cap:
        raise InvalidArgument(f'{what} must be between 1 and {cap}; got {num_solutions}')
    return int(num_solutions)


def check_obstacles(obstacles, cap: int) -> List[Obstacle]:
    """A list of :class:`Obstacle` from a sequence of obstacles or dicts, at most ``cap``.

    Raises:
        InvalidArgument: not a list or tuple, a bad obstacle, or more than ``cap``.
    """
    if obstacles is None or isinstance(obstacles, (str, bytes, dict, Obstacle)) or not \
            isinstance(obstacles, (list, tuple)):
        raise InvalidArgument(f'obstacles must be a list of Obstacle (or dicts); got '
                              f'{type(obstacles).__name__}')
    if len(obstacles) > cap:
        raise InvalidArgument(f'{len(obstacles)} obstacles; at most {cap} are accepted '
                              f'(SolverConfig.max_obstacles)')
    return [Obstacle.of(o) for o in obstacles]


def check_objective(objective):
    """None or a callable cost over configurations, or :class:`InvalidArgument`."""
    if objective is not None and not callable(objective):
        raise InvalidArgument(f'objective must be an Objective (a callable cost) or None; got '
                              f'{type(objective).__name__}')
    return objective


def check_seed(robot: Robot, seed) -> np.ndarray:
    """A seed as a (n,) array within the limits, or :class:`InvalidSeed` saying what is wrong."""
    q = real_array(seed, 'seed', InvalidSeed, f'{robot.dof} numbers')
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
