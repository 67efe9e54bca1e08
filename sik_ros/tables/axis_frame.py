"""The frame of an arm's first joint axis, and tip poses in it.

A revolute first joint turns the whole arm about a line fixed to the base (:func:`first_axis`):
a pose turned about that line is reached by turning the first joint alike. The seed table
(:mod:`sik_ros.tables.seed_table`) keys its rows by their tip poses in that frame
(:func:`to_axis_frame`), turned to azimuth 0 (:func:`turned`).
"""

from typing import Optional, Tuple

import numpy as np

from sik_ros.kinematics.chain import chain_forward
from sik_ros.kinematics.robot import Robot
from sik_ros.kinematics.rotations import rotation_to_quaternion, z_to_axis

#: The turn [rad] of the first joint with which :func:`first_axis` checks an arm.
BASE_CHECK_ANGLE = 0.7


def first_axis(robot: Robot) -> Optional[Tuple[np.ndarray, np.ndarray]]:
    """The first joint's axis as a frame: origin (3,) and rotation (3, 3) whose z is the axis.

    A revolute first joint turns the whole arm about this line, fixed to the base. A sanity
    check on a few fixed configurations (the tip poses with the first joint turned by
    :data:`BASE_CHECK_ANGLE` equal the tip poses turned about the line, to 1e-9); None if
    they differ (it cannot for a serial chain of revolute joints).
    """
    zero = np.zeros((1, robot.dof))
    _, _, origins, axes = chain_forward(robot.chain, zero, frames=True)
    origin, axis = origins[0, 0], axes[0, 0] / np.linalg.norm(axes[0, 0])
    frame = (origin, z_to_axis(axis))
    q = np.random.default_rng(0).uniform(robot.lower, robot.upper, (8, robot.dof))
    moved = q.copy()
    moved[:, 0] += BASE_CHECK_ANGLE
    p, quat = to_axis_frame(frame, *robot.fk_batch(q))
    p2, quat2 = to_axis_frame(frame, *robot.fk_batch(moved))
    pt, qt = turned(p, quat, np.full(len(q), BASE_CHECK_ANGLE))
    if np.allclose(pt, p2, rtol=0, atol=1e-9) and np.allclose(
            np.abs(np.einsum('ij,ij->i', qt, quat2)), 1.0, rtol=0, atol=1e-12):
        return frame
    return None


def to_axis_frame(frame: Tuple[np.ndarray, np.ndarray], p: np.ndarray, quat: np.ndarray,
                  inverse: Optional[np.ndarray] = None) -> Tuple[np.ndarray, np.ndarray]:
    """Positions (N, 3) and quaternions (N, 4, x y z w) in ``frame`` (origin, rotation).

    ``inverse``: the frame's inverse rotation as a quaternion (x y z w), when already known.
    """
    origin, rot = frame
    if inverse is None:
        inverse = rotation_to_quaternion(rot.T[None])[0]
    cx, cy, cz, cw = inverse
    x, y, z, w = quat.T
    q = np.stack([cw * x + cx * w + cy * z - cz * y, cw * y - cx * z + cy * w + cz * x,
                  cw * z + cx * y - cy * x + cz * w, cw * w - cx * x - cy * y - cz * z], axis=1)
    return (p - origin) @ rot, q


def turned(p: np.ndarray, quat: np.ndarray, angle: np.ndarray
           ) -> Tuple[np.ndarray, np.ndarray]:
    """Positions (N, 3) and quaternions (N, 4: x y z w, w >= 0) turned by ``angle`` about z."""
    c, s = np.cos(angle), np.sin(angle)
    pt = np.stack([c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1], p[:, 2]], axis=1)
    # (0, 0, sin(a/2), cos(a/2)) times quat
    sa, ca = np.sin(angle / 2), np.cos(angle / 2)
    x, y, z, w = quat.T
    qt = np.stack([ca * x - sa * y, ca * y + sa * x, ca * z + sa * w, ca * w - sa * z], axis=1)
    return pt, np.where(qt[:, 3:4] < 0, -qt, qt)
