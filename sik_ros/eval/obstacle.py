"""Experiment 6, obstacle avoidance: a box the first unconstrained solution hits; Algorithm 2.

The box stands on the table between the base and the goal (:func:`place_box`); the solver, given
the box as an obstacle, ranks collision-free exact solutions first and runs the posture-index
adjustment (Algorithm 2) when none of its decoded candidates is free.
"""

from dataclasses import dataclass
from typing import Optional, Sequence, Tuple, Union

import numpy as np

from sik_ros.eval.metrics import position_errors
from sik_ros.kinematics.collision import CollisionChecker, Obstacle
from sik_ros.solver import SelectiveIK

#: Goals tried in turn for the obstacle case [m].
OBSTACLE_GOALS = ((0.6, 0.0, 0.1), (0.5, -0.3, 0.15), (0.5, 0.3, 0.15), (0.65, 0.1, 0.3),
                  (0.45, 0.0, 0.05))


def place_box(checker: CollisionChecker, q: np.ndarray, goal: np.ndarray,
              heights: Sequence[float] = (0.15, 0.2, 0.25, 0.3, 0.4),
              size: Tuple[float, float] = (0.1, 0.3)) -> Optional[Obstacle]:
    """A box standing on the table (z = 0) between the base and the goal that a posture hits.

    The box (``size``: depth along the base-goal line, width across it [m]) is turned to face
    the line and slid along it from near the goal towards the base, for the lowest height first;
    the first place where the posture ``q`` hits it while the goal stays at least 5 cm outside
    it is returned (None if there is none).
    """
    reach = float(np.linalg.norm(goal[:2]))
    if reach < 0.35:
        return None
    u = goal[:2] / reach
    yaw = float(np.arctan2(u[1], u[0]))
    quat = (0.0, 0.0, float(np.sin(yaw / 2)), float(np.cos(yaw / 2)))
    for h in heights:
        for d in np.arange(reach - size[0] / 2 - 0.06, 0.25, -0.02):
            centre = (float(d * u[0]), float(d * u[1]), h / 2)
            box = Obstacle('box', (size[0], size[1], h), centre, quat)
            local = np.abs(_rotate_z(goal - np.array(centre), -yaw)) - np.array(box.dimensions) / 2
            if np.linalg.norm(np.maximum(local, 0)) < 0.05:
                continue
            if checker.clearance(q[None], [box])[0] <= 0:
                return box
    return None


def _rotate_z(v: np.ndarray, angle: float) -> np.ndarray:
    """A vector (3,) turned about z by ``angle`` [rad]."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]])


@dataclass
class ObstacleCase:
    """Experiment 6's result.

    Attributes:
        goal: the goal position (3,) [m].
        box: the box the first unconstrained solution hits.
        q_first: that solution (n,) [rad]; ``clearance_first`` its clearance from the box [m].
        q_chosen: the solution chosen with the box as an obstacle (n,) [rad].
        clearance_chosen: its clearance from the box [m] (negative: penetration).
        error_chosen: its distance error [m].
        converged: whether it is within the solver's tolerance.
        from_adjustment: the chosen posture is none of the unconstrained solutions.
        unconstrained_total: how many unconstrained solutions there were.
        unconstrained_colliding: how many of those hit the box.
        elapsed_s: the time of the solve with the box [s].
    """

    goal: np.ndarray
    box: Obstacle
    q_first: np.ndarray
    clearance_first: float
    q_chosen: np.ndarray
    clearance_chosen: float
    error_chosen: float
    converged: bool
    from_adjustment: bool
    unconstrained_total: int
    unconstrained_colliding: int
    elapsed_s: float


@dataclass
class NoObstacleCase:
    """Experiment 6 not run: why no goal gave a usable box."""

    reason: str
    goal: None = None


def obstacle_study(ik: SelectiveIK, goals: Sequence = OBSTACLE_GOALS,
                   num_solutions: int = 16) -> Union[ObstacleCase, NoObstacleCase]:
    """Experiment 6: a box the first unconstrained solution hits; Algorithm 2's answer.

    For the first goal [m] where a box can be placed (:func:`place_box`) so that the
    first-ranked unconstrained solution collides with it, solve again with the box as an
    obstacle (asking ``num_solutions``).
    """
    for g in goals:
        goal = np.asarray(g, dtype=float)
        free = ik.solve(goal, num_solutions=ik.config.max_solutions_cap)
        if not free.solutions:
            continue
        first = free.solutions[0]
        box = place_box(ik.checker, first.q, goal)
        if box is None:
            continue
        clear_all = ik.checker.clearance(np.array([s.q for s in free.solutions]), [box])
        if clear_all[0] > 0:
            continue
        res = ik.solve(goal, num_solutions=num_solutions, obstacles=[box])
        chosen = res.solutions[0]
        seen = any(np.allclose(chosen.q, s.q, atol=1e-6) for s in free.solutions)
        return ObstacleCase(
            goal, box, first.q, float(clear_all[0]), chosen.q,
            float(chosen.min_obstacle_distance),
            float(position_errors(ik.robot, chosen.q, goal)[0]), bool(chosen.converged),
            not seen, len(free.solutions), int(np.sum(clear_all <= 0)), float(res.elapsed))
    return NoObstacleCase('no goal gave a box that the first solution hits while leaving the '
                          'goal free')
