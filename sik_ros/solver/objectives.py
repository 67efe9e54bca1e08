"""Evaluation functions for ranking and adjusting solutions (the paper's Algorithm 2).

An objective maps a batch of joint configurations (N, n) [rad] to costs (N,), lower is better.
Objectives compose with ``+`` and scalar ``*``. Obstacles and collision checks live in
:mod:`sik_ros.kinematics.collision`.
"""

from typing import Callable, List, Optional, Sequence

import numpy as np

from sik_ros.errors import InvalidArgument
from sik_ros.kernels import as_arg
from sik_ros.kernels.sets import margin_costs
from sik_ros.kinematics.chain import chain_forward
from sik_ros.kinematics.collision import CollisionChecker, Obstacle
from sik_ros.kinematics.robot import Robot


class Objective:
    """A cost over configurations; lower is better. Compose with + and scalar *."""

    def __call__(self, q: np.ndarray) -> np.ndarray:
        """Costs (N,) of configurations (N, n)."""
        raise NotImplementedError

    def __add__(self, other: 'Objective') -> 'Objective':
        """The sum of two objectives."""
        return Sum([self, other])

    def __rmul__(self, weight: float) -> 'Objective':
        """A weighted objective."""
        return Weighted(self, float(weight))


class Sum(Objective):
    """The sum of several objectives."""

    def __init__(self, terms: Sequence[Objective]):
        self.terms = list(terms)

    def __call__(self, q):
        """Sum of the terms' costs."""
        return np.sum([t(q) for t in self.terms], axis=0)


class Weighted(Objective):
    """An objective times a weight."""

    def __init__(self, term: Objective, weight: float):
        self.term, self.weight = term, weight

    def __call__(self, q):
        """Weighted cost."""
        return self.weight * self.term(q)


class FromFunction(Objective):
    """Any function (N, n) -> (N,) as an objective."""

    def __init__(self, fn: Callable[[np.ndarray], np.ndarray]):
        self.fn = fn

    def __call__(self, q):
        """The function's cost."""
        return np.asarray(self.fn(np.asarray(q, dtype=float)), dtype=float)


class SeedDistance(Objective):
    """Distance to a reference configuration [rad] (keep close to the current state)."""

    def __init__(self, seed: np.ndarray, weights: Optional[np.ndarray] = None):
        self.seed = np.asarray(seed, dtype=float)
        self.weights = np.ones_like(self.seed) if weights is None else np.asarray(weights)

    def __call__(self, q):
        """Weighted L2 distance to the seed."""
        return np.linalg.norm((np.asarray(q) - self.seed) * self.weights, axis=1)


class JointLimitMargin(Objective):
    """Closeness to the joint limits: 1 - the smallest normalised margin (0 to 1).

    The default ranking without a seed, everywhere (:func:`sik_ros.solver.ranking.rank`, and
    the lean path's :func:`~sik_ros.kernels.sets.exact_by_margin`): one compiled formula,
    :func:`~sik_ros.kernels.sets.margin_cost`.
    """

    def __init__(self, robot: Robot):
        self.lower, self.upper = as_arg(robot.lower), as_arg(robot.upper)

    def __call__(self, q):
        """Cost in [0, 1]."""
        return margin_costs(as_arg(np.atleast_2d(q)), self.lower, self.upper)


class ElbowHeight(Objective):
    """Prefer a high (or, with ``prefer='low'``, a low) elbow: cost = -+ elbow z [m].

    ``elbow_joint`` is the index of the elbow joint in the chain; by default the middle one,
    ``(n - 1) // 2`` (the Panda's joint 4, a UR's or a Kinova's joint 3).
    """

    def __init__(self, robot: Robot, elbow_joint: Optional[int] = None, prefer: str = 'high'):
        elbow_joint = (robot.dof - 1) // 2 if elbow_joint is None else elbow_joint
        if not 0 <= elbow_joint < robot.dof:
            raise InvalidArgument(f'elbow_joint must be in 0..{robot.dof - 1}; got {elbow_joint}')
        self.robot, self.joint = robot, elbow_joint
        if prefer not in ('high', 'low'):
            raise InvalidArgument(f"prefer must be 'high' or 'low'; got {prefer!r}")
        self.sign = -1.0 if prefer == 'high' else 1.0

    def __call__(self, q):
        """Signed elbow height."""
        _, _, origins, _ = chain_forward(self.robot.chain, np.asarray(q, dtype=float),
                                         frames=True)
        return self.sign * origins[:, self.joint, 2]


class Manipulability(Objective):
    """Prefer dexterous postures: cost = -sqrt(det(J J^T)) of the position Jacobian."""

    def __init__(self, robot: Robot):
        self.robot = robot

    def __call__(self, q):
        """Negative Yoshikawa manipulability."""
        _, _, jac = self.robot.jacobian_batch(np.asarray(q, dtype=float))
        jp = jac[:, :3]
        return -np.sqrt(np.clip(np.linalg.det(jp @ jp.transpose(0, 2, 1)), 0, None))


class ObstacleClearance(Objective):
    """Prefer clearance from obstacles: cost = -min(clearance, cap) [m]."""

    def __init__(self, checker: CollisionChecker, obstacles: List[Obstacle], cap: float = 0.2):
        self.checker, self.obstacles, self.cap = checker, list(obstacles), cap

    def __call__(self, q):
        """Negative capped clearance."""
        return -np.minimum(self.checker.clearance(q, self.obstacles), self.cap)
