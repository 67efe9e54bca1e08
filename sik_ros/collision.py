"""Collision geometry: obstacles (box, sphere, cylinder) and the robot's clearance from them.

Distances and self-collision come from the robot's collision geometry through Pinocchio and coal.
"""

from dataclasses import dataclass
from typing import Sequence

import coal
import numpy as np
import pinocchio as pin

from sik_ros.errors import InvalidArgument
from sik_ros.kinematics import Robot
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
