"""Collision geometry: obstacles (box, sphere, cylinder) and the robot's clearance from them.

Distances and self-collision come from the robot's collision geometry through Pinocchio and coal.
"""

from dataclasses import dataclass
from typing import Sequence

import coal
import numpy as np
import pinocchio as pin

from sik_ros.deadline import Deadline, NO_DEADLINE
from sik_ros.errors import InvalidArgument
from sik_ros.kinematics.robot import Robot
from sik_ros.validation import MAX_DISTANCE, quaternion, vector

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
        if not isinstance(self.shape, str) or self.shape not in need:
            raise InvalidArgument(f'obstacle shape must be box, sphere or cylinder; '
                                  f'got {self.shape!r}')
        try:
            dims = np.asarray(self.dimensions, dtype=float)
        except (TypeError, ValueError, OverflowError):
            dims = np.array([np.nan])
        if dims.shape != (need[self.shape],) or not np.all(np.isfinite(dims)) \
                or np.any(dims <= 0) or np.any(dims > 2 * MAX_DISTANCE):
            raise InvalidArgument(f'{self.shape} obstacle needs {need[self.shape]} positive '
                                  f'dimensions (up to {2 * MAX_DISTANCE:g} m); got '
                                  f'{self.dimensions!r}')
        vector(self.position, 3, 'obstacle position', limit=MAX_DISTANCE)
        quaternion(self.quaternion, 'obstacle')

    @property
    def bounding_radius(self) -> float:
        """Radius of a sphere about ``position`` that holds the obstacle [m]."""
        d = np.asarray(self.dimensions, dtype=float)
        if self.shape == BOX:
            return 0.5 * float(np.linalg.norm(d))
        if self.shape == SPHERE:
            return float(d[0])
        return float(np.hypot(d[0] / 2, d[1]))

    def geometry(self) -> coal.CollisionGeometry:
        """The coal shape."""
        d = [float(x) for x in self.dimensions]
        if self.shape == BOX:
            return coal.Box(*d)
        if self.shape == SPHERE:
            return coal.Sphere(d[0])
        return coal.Cylinder(d[1], d[0])

    @classmethod
    def of(cls, value) -> 'Obstacle':
        """An :class:`Obstacle`, or one from a dict of its fields.

        Raises:
            InvalidArgument: neither, or a dict with unknown or missing fields.
        """
        if isinstance(value, Obstacle):
            return value
        if isinstance(value, dict):
            known = {'shape', 'dimensions', 'position', 'quaternion'}
            unknown = sorted(set(map(str, value)) - known)
            if unknown or not {'shape', 'dimensions'} <= set(value):
                keys = sorted(map(str, value))
                raise InvalidArgument(f'an obstacle dict needs shape and dimensions (and may '
                                      f'have position, quaternion); got keys {keys}')
            return cls(**value)
        raise InvalidArgument(f'an obstacle must be an Obstacle or a dict of its fields; got '
                              f'{type(value).__name__}')

    def placement(self) -> pin.SE3:
        """Pose in the base frame."""
        x, y, z, w = quaternion(self.quaternion, 'obstacle')
        return pin.SE3(pin.Quaternion(w, x, y, z).toRotationMatrix(),
                       np.asarray(self.position, dtype=float))


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
        self._drop_adjacent_pairs()
        self.self_data = pin.GeometryData(self.self_geom)
        # coal's naive broad phase: each pair's bounding boxes before its narrow phase (the
        # same answers, in less time: docs/design.md, "Measured choices")
        self._broad = pin.BroadPhaseManager_NaiveCollisionManager(self.model, self.self_geom,
                                                                  self.self_data)
        self.geom_data = pin.GeometryData(self.geom)
        # each robot part's bounding sphere: its local box's centre and half diagonal [m]
        centers, radii = [], []
        for obj in self.geom.geometryObjects:
            obj.geometry.computeLocalAABB()
            box = obj.geometry.aabb_local
            centers.append(np.asarray(box.center(), dtype=float))
            radii.append(0.5 * float(np.linalg.norm(np.asarray(box.max_) - np.asarray(box.min_))))
        self._local_centers, self._radii = centers, np.array(radii)

    def _drop_adjacent_pairs(self) -> None:
        """Leave out pairs of parts on one link or on two links a joint connects.

        Their meshes touch at the joint in every posture (MoveIt's "adjacent" rule); an SRDF,
        when the robot has one, disables more.
        """
        objs, parents = self.self_geom.geometryObjects, self.model.parents
        for k in reversed(range(len(self.self_geom.collisionPairs))):
            pair = self.self_geom.collisionPairs[k]
            a, b = objs[pair.first].parentJoint, objs[pair.second].parentJoint
            if a == b or parents[a] == b or parents[b] == a:
                self.self_geom.removeCollisionPair(pair)

    def self_collision(self, q: np.ndarray, deadline: Deadline = NO_DEADLINE) -> np.ndarray:
        """Whether each configuration (N, n) collides with itself, (N,) bool.

        Past ``deadline`` no more checks start (the first is always made): the answer then
        holds only the configurations checked, in order (shorter than ``q``).
        """
        out = np.zeros(len(q), dtype=bool)
        for i, qi in enumerate(np.asarray(q, dtype=float)):
            if i and deadline.expired():
                return out[:i]
            out[i] = pin.computeCollisions(self.model, self.data, self._broad, qi, True)
        return out

    def clearance(self, q: np.ndarray, obstacles: Sequence[Obstacle],
                  deadline: Deadline = NO_DEADLINE) -> np.ndarray:
        """Smallest signed distance from the robot to any obstacle [m], (N,); +inf if none.

        Negative values are penetration depths. A broad phase keeps the cost near-linear in the
        obstacles: bounding spheres give every robot part-obstacle pair a lower bound, and
        exact distances (coal's GJK/EPA) are computed in order of it until the bound exceeds
        the smallest distance found. Configurations not reached by ``deadline`` are NaN
        (unknown).
        """
        q = np.asarray(q, dtype=float)
        if not obstacles:
            return np.full(len(q), np.inf)
        shapes = [(o.geometry(), o.placement()) for o in obstacles]
        o_center = np.array([o.position for o in obstacles], dtype=float)
        o_radius = np.array([o.bounding_radius for o in obstacles])
        out = np.full(len(q), np.nan)
        request, result = coal.DistanceRequest(), coal.DistanceResult()
        for i, qi in enumerate(q):
            if i and deadline.expired():
                break
            pin.updateGeometryPlacements(self.model, self.data, self.geom, self.geom_data, qi)
            placements = [self.geom_data.oMg[r] for r in range(self.n_robot)]
            centers = np.array([pl.act(c) for pl, c in zip(placements, self._local_centers)])
            bound = (np.linalg.norm(centers[:, None] - o_center[None], axis=2)
                     - self._radii[:, None] - o_radius[None])
            best = np.inf
            for flat in np.argsort(bound, axis=None):
                r, k = divmod(int(flat), len(obstacles))
                if bound[r, k] >= best:
                    break
                result.clear()
                d = coal.distance(self.geom.geometryObjects[r].geometry,
                                  coal.Transform3s(placements[r].rotation,
                                                   placements[r].translation),
                                  shapes[k][0], coal.Transform3s(shapes[k][1].rotation,
                                                                 shapes[k][1].translation),
                                  request, result)
                best = min(best, d)
            out[i] = best
        return out
