"""Constraints an answer must meet beyond its goal: joint ranges, link regions and orientations.

MoveIt's ``moveit_msgs/Constraints`` in library form, checked on a solution
(:meth:`GoalConstraints.violation`): a joint within ``[position - below, position + above]``, a
point of a link inside a region (a union of boxes, spheres and cylinders), a link's orientation
within per-axis tolerances of a target (errors as intrinsic x-y-z Euler angles or as a rotation
vector, as MoveIt measures them). The joint ranges also steer the search:
:class:`JointRangeCost` ranks solutions by their distance from a seed plus a steep cost for
leaving the ranges, so that the solver's best answers lie inside them when it finds such.
"""

from dataclasses import dataclass, field
import math
from typing import Dict, Optional, Sequence, Tuple

import numpy as np
from scipy.spatial.transform import Rotation

from sik_ros.errors import InvalidGoal
from sik_ros.kinematics.link_frames import LinkFrames, Transform
from sik_ros.solver.objectives import Objective

#: Slack of every check, as MoveIt's (a double's machine epsilon is far below it) [m or rad].
SLACK = 1e-9
#: Cost of each radian outside a joint range, against radians of distance from the seed.
OUTSIDE_WEIGHT = 1e3
#: Region shapes: their dimensions, as ``shape_msgs/SolidPrimitive`` gives them.
SHAPES = {'box': 3, 'sphere': 1, 'cylinder': 2}


class InvalidConstraint(InvalidGoal):
    """A constraint that cannot be checked: unknown joint or link, bad numbers, a shape."""


@dataclass(frozen=True)
class Region:
    """A shape placed in the base frame.

    Attributes:
        kind: ``box`` (dimensions x y z), ``sphere`` (radius) or ``cylinder`` (height, radius;
            along its z axis), each centred on its pose [m].
        dimensions: the shape's dimensions [m].
        pose: the shape's pose in the base frame.
    """

    kind: str
    dimensions: Tuple[float, ...]
    pose: Transform

    def __post_init__(self):
        """Check the kind and the dimensions.

        Raises:
            InvalidConstraint: an unknown kind, or dimensions that are not positive numbers.
        """
        if self.kind not in SHAPES:
            raise InvalidConstraint(f'region shape {self.kind!r} is not supported '
                                    f'({", ".join(SHAPES)})')
        dims = np.asarray(self.dimensions, dtype=float)
        if dims.shape != (SHAPES[self.kind],) or not np.all(np.isfinite(dims)) \
                or np.any(dims < 0):
            raise InvalidConstraint(f'a {self.kind} region needs {SHAPES[self.kind]} finite '
                                    f'dimensions >= 0; got {list(self.dimensions)}')

    def contains(self, point: np.ndarray) -> bool:
        """Whether a point of the base frame (3,) [m] is inside the shape."""
        local = self.pose.rotation.T @ (np.asarray(point, dtype=float) - self.pose.translation)
        d = self.dimensions
        if self.kind == 'box':
            return bool(np.all(np.abs(local) <= np.asarray(d) / 2 + SLACK))
        if self.kind == 'sphere':
            return bool(np.linalg.norm(local) <= d[0] + SLACK)
        return bool(abs(local[2]) <= d[0] / 2 + SLACK
                    and math.hypot(local[0], local[1]) <= d[1] + SLACK)


@dataclass(frozen=True)
class PositionRule:
    """A point fixed to a link must lie in one of some regions.

    Attributes:
        link: the link.
        offset: the point in the link's frame (3,) [m].
        regions: the regions (their union); at least one.
    """

    link: str
    offset: np.ndarray
    regions: Tuple[Region, ...]


@dataclass(frozen=True)
class OrientationRule:
    """A link's orientation must stay within per-axis tolerances of a target.

    Attributes:
        link: the link.
        target: the target rotation in the base frame (3, 3).
        tolerance: the largest error about x, y, z [rad].
        rotation_vector: measure the error as a rotation vector (else as intrinsic x-y-z Euler
            angles).
    """

    link: str
    target: np.ndarray
    tolerance: np.ndarray
    rotation_vector: bool = False

    def error(self, rotation: np.ndarray) -> np.ndarray:
        """Return the absolute error about each axis (3,) [rad] of a link rotation (3, 3)."""
        diff = Rotation.from_matrix(self.target.T @ rotation)
        if self.rotation_vector:
            return np.abs(diff.as_rotvec())
        # scipy's intrinsic x-y-z angles keep the middle one within [-pi/2, pi/2]: a small
        # error rotation has three small angles
        return np.abs(diff.as_euler('XYZ'))


@dataclass(frozen=True)
class GoalConstraints:
    """What a solution must meet besides its goal.

    Attributes:
        lower: lowest value of each arm joint (n,) [rad] (-inf: unbounded).
        upper: highest value of each arm joint (n,) [rad] (+inf: unbounded).
        others: ranges of joints outside the arm: name -> (lower, upper) [rad], checked against
            the values the request gave them.
        positions: the position rules.
        orientations: the orientation rules.
    """

    lower: np.ndarray
    upper: np.ndarray
    others: Dict[str, Tuple[float, float]] = field(default_factory=dict)
    positions: Tuple[PositionRule, ...] = ()
    orientations: Tuple[OrientationRule, ...] = ()

    @property
    def bounds_joints(self) -> bool:
        """Whether some arm joint has a range."""
        return bool(np.any(np.isfinite(self.lower)) or np.any(np.isfinite(self.upper)))

    @property
    def empty(self) -> bool:
        """Whether nothing is constrained."""
        return not (self.bounds_joints or self.others or self.positions or self.orientations)

    def violation(self, q: np.ndarray, joint_names: Sequence[str], frames: LinkFrames,
                  given: Dict[str, float]) -> Optional[str]:
        """Why a solution ``q`` (n,) [rad] breaks the constraints, or None when it meets them.

        Args:
            q: the arm's joint values [rad].
            joint_names: the arm's joint names, in the order of ``q``.
            frames: the links of the arm's description.
            given: values of joints outside the arm [rad], by name.
        """
        q = np.asarray(q, dtype=float)
        out = (q < self.lower - SLACK) | (q > self.upper + SLACK)
        if out.any():
            i = int(np.argmax(out))
            return (f'joint {joint_names[i]} = {q[i]:.6g} rad is outside its constraint '
                    f'[{self.lower[i]:.6g}, {self.upper[i]:.6g}]')
        for name, (lo, hi) in self.others.items():
            value = given.get(name)
            if value is None or not lo - SLACK <= value <= hi + SLACK:
                return f'joint {name} = {value} rad is outside its constraint [{lo}, {hi}]'
        links = [r.link for r in self.positions] + [r.link for r in self.orientations]
        poses = dict(zip(links, frames.poses(q, links))) if links else {}
        for rule in self.positions:
            pose = poses[rule.link]
            point = pose.rotation @ rule.offset + pose.translation
            if not any(region.contains(point) for region in rule.regions):
                return (f'link {rule.link} point {np.round(point, 6).tolist()} m is outside '
                        f'its position constraint region')
        for rule in self.orientations:
            error = rule.error(poses[rule.link].rotation)
            if np.any(error > rule.tolerance + SLACK):
                return (f'link {rule.link} orientation error {np.round(error, 6).tolist()} rad '
                        f'exceeds its tolerance {rule.tolerance.tolist()}')
        return None


def no_constraints(dof: int) -> GoalConstraints:
    """Constraints that every solution of an arm with ``dof`` joints meets."""
    return GoalConstraints(np.full(dof, -np.inf), np.full(dof, np.inf))


class JointRangeCost(Objective):
    """Distance from a seed [rad] plus :data:`OUTSIDE_WEIGHT` per radian outside the ranges."""

    def __init__(self, seed: Optional[np.ndarray], lower: np.ndarray, upper: np.ndarray):
        """Rank by distance from ``seed`` (None: by the outside cost alone) within ranges."""
        self.seed = None if seed is None else np.asarray(seed, dtype=float)
        self.lower, self.upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)

    def __call__(self, q):
        """Costs (N,) of configurations (N, n)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        outside = np.maximum(self.lower - q, 0.0) + np.maximum(q - self.upper, 0.0)
        cost = OUTSIDE_WEIGHT * outside.sum(axis=1)
        if self.seed is not None:
            cost = cost + np.linalg.norm(q - self.seed, axis=1)
        return cost
