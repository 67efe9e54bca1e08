"""Evaluation functions for ranking and adjusting solutions (the paper's Algorithm 2).

An objective maps a batch of joint configurations (N, n) [rad] to costs (N,), lower is better.
Objectives compose with ``+`` and scalar ``*``. Collision checks use the robot's collision
geometry through Pinocchio and coal.
"""

from dataclasses import dataclass
from typing import Callable, List, Optional, Sequence

import coal
import numpy as np
import pinocchio as pin

from sik_ros.errors import InvalidArgument
from sik_ros.kinematics import chain_forward, Robot

BOX, SPHERE, CYLINDER = 'box', 'sphere', 'cylinder'


@dataclass(frozen=True)
class Obstacle:
    """A box, sphere or cylinder in the base frame.

    Attributes:
        shape: ``box``, ``sphere`` or ``cylinder``.
        dimensions: box (x, y, z) side lengths; sphere (radius,); cylinder (height, radius),
            as in ``shape_msgs/SolidPrimitive`` [m].
        position: centre in the base frame [m].
        quaternion: orientation x y z w.
    """

    shape: str
    dimensions: tuple
    position: tuple = (0.0, 0.0, 0.0)
    quaternion: tuple = (0.0, 0.0, 0.0, 1.0)

    def __post_init__(self):
        """Validate shape, sizes and pose."""
        need = {BOX: 3, SPHERE: 1, CYLINDER: 2}
        if self.shape not in need:
            raise InvalidArgument(f'obstacle shape must be box, sphere or cylinder; '
                                  f'got {self.shape!r}')
        dims = np.asarray(self.dimensions, dtype=float)
        if dims.shape != (need[self.shape],) or not np.all(np.isfinite(dims)) \
                or np.any(dims <= 0):
            raise InvalidArgument(f'{self.shape} obstacle needs {need[self.shape]} positive '
                                  f'dimensions; got {list(self.dimensions)}')
        pos = np.asarray(self.position, dtype=float)
        quat = np.asarray(self.quaternion, dtype=float)
        if pos.shape != (3,) or not np.all(np.isfinite(pos)):
            raise InvalidArgument(f'obstacle position must be 3 finite numbers; got {pos}')
        if quat.shape != (4,) or not np.all(np.isfinite(quat)) or np.linalg.norm(quat) < 1e-9:
            raise InvalidArgument(f'obstacle quaternion must be 4 finite numbers, not all '
                                  f'zero; got {quat}')

    def geometry(self) -> coal.CollisionGeometry:
        """The coal shape."""
        d = [float(x) for x in self.dimensions]
        if self.shape == BOX:
            return coal.Box(*d)
        if self.shape == SPHERE:
            return coal.Sphere(d[0])
        return coal.Cylinder(d[1], d[0])

    def placement(self) -> pin.SE3:
        """Pose in the base frame."""
        x, y, z, w = np.asarray(self.quaternion, dtype=float) / np.linalg.norm(self.quaternion)
        return pin.SE3(pin.Quaternion(w, x, y, z).toRotationMatrix(),
                       np.asarray(self.position, dtype=float))


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
    """Closeness to the joint limits: 1 - the smallest normalised margin (0 to 1)."""

    def __init__(self, robot: Robot):
        self.lower, self.upper = robot.lower, robot.upper

    def __call__(self, q):
        """Cost in [0, 1]."""
        half = (self.upper - self.lower) / 2
        margin = np.minimum(q - self.lower, self.upper - q) / half
        return 1.0 - margin.min(axis=1)


class ElbowHeight(Objective):
    """Prefer a high (or, with ``prefer='low'``, a low) elbow: cost = -+ elbow z [m]."""

    def __init__(self, robot: Robot, elbow_joint: int = 3, prefer: str = 'high'):
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


class CollisionChecker:
    """Distances between the robot's collision geometry and obstacles, and self-collision.

    Not thread-safe: it owns Pinocchio and coal data; use one per thread.
    """

    def __init__(self, robot: Robot):
        self.robot = robot
        self.model = robot.model
        self.data = robot.model.createData()
        self.geom = robot.collision_model
        self.n_robot = self.geom.ngeoms
        self.self_geom = self.geom.copy()
        self.self_geom.addAllCollisionPairs()
        if robot.srdf_path is not None:
            pin.removeCollisionPairs(self.model, self.self_geom, str(robot.srdf_path))
        self.self_data = pin.GeometryData(self.self_geom)

    def self_collision(self, q: np.ndarray) -> np.ndarray:
        """Whether each configuration (N, n) collides with itself, (N,) bool."""
        out = np.zeros(len(q), dtype=bool)
        for i, qi in enumerate(np.asarray(q, dtype=float)):
            out[i] = pin.computeCollisions(self.model, self.data, self.self_geom,
                                           self.self_data, qi, True)
        return out

    def clearance(self, q: np.ndarray, obstacles: Sequence[Obstacle]) -> np.ndarray:
        """Smallest signed distance from the robot to any obstacle [m], (N,); +inf if none.

        Negative values are penetration depths.
        """
        q = np.asarray(q, dtype=float)
        if not obstacles:
            return np.full(len(q), np.inf)
        geom = self.geom.copy()
        for k, obs in enumerate(obstacles):
            obj = pin.GeometryObject(f'obstacle_{k}', 0, 0, obs.placement(), obs.geometry())
            gid = geom.addGeometryObject(obj)
            for r in range(self.n_robot):
                geom.addCollisionPair(pin.CollisionPair(r, gid))
        gdata = pin.GeometryData(geom)
        out = np.empty(len(q))
        for i, qi in enumerate(q):
            pin.computeDistances(self.model, self.data, geom, gdata, qi)
            out[i] = min(r.min_distance for r in gdata.distanceResults)
        return out


class ObstacleClearance(Objective):
    """Prefer clearance from obstacles: cost = -min(clearance, cap) [m]."""

    def __init__(self, checker: CollisionChecker, obstacles: List[Obstacle], cap: float = 0.2):
        self.checker, self.obstacles, self.cap = checker, list(obstacles), cap

    def __call__(self, q):
        """Negative capped clearance."""
        return -np.minimum(self.checker.clearance(q, self.obstacles), self.cap)
