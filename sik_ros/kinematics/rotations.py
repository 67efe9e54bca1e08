"""Rotation helpers: quaternions, the SO(3) logarithm and the angle between rotations."""

import math

import numpy as np
from scipy.spatial.transform import Rotation


def z_to_axis(axis: np.ndarray) -> np.ndarray:
    """A rotation that maps the z axis onto a unit ``axis``."""
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(z, axis)
    sin, cos = np.linalg.norm(v), float(z @ axis)
    if sin < 1e-12:
        return np.eye(3) if cos > 0 else np.diag([1.0, -1.0, -1.0])
    return Rotation.from_rotvec(v / sin * np.arctan2(sin, cos)).as_matrix()


def quaternion_matrix(quat) -> np.ndarray:
    """The rotation matrix (3, 3) of one quaternion x y z w (normalised first).

    scipy's ``Rotation.from_quat(quat).as_matrix()``, in Python floats: for one request's goal
    this costs a fraction of scipy's call, most of all when scipy's code is out of the caches.
    """
    x, y, z, w = (float(v) for v in quat)
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    x2, y2, z2, w2 = x * x, y * y, z * z, w * w
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    return np.array([[x2 - y2 - z2 + w2, 2 * (xy - zw), 2 * (xz + yw)],
                     [2 * (xy + zw), -x2 + y2 - z2 + w2, 2 * (yz - xw)],
                     [2 * (xz - yw), 2 * (yz + xw), -x2 - y2 + z2 + w2]])


def matrix_quaternion(rot) -> np.ndarray:
    """The unit quaternion (4,), x y z w with w >= 0, of one rotation matrix (3, 3).

    Shepperd's method in Python floats: for one goal far cheaper than scipy's
    ``Rotation.from_matrix`` call.
    """
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = (
        (float(v) for v in row) for row in np.asarray(rot))
    trace = r00 + r11 + r22
    if trace > 0:
        s = 2 * math.sqrt(trace + 1)
        x, y, z, w = (r21 - r12) / s, (r02 - r20) / s, (r10 - r01) / s, s / 4
    elif r00 > r11 and r00 > r22:
        s = 2 * math.sqrt(1 + r00 - r11 - r22)
        x, y, z, w = s / 4, (r01 + r10) / s, (r02 + r20) / s, (r21 - r12) / s
    elif r11 > r22:
        s = 2 * math.sqrt(1 + r11 - r00 - r22)
        x, y, z, w = (r01 + r10) / s, s / 4, (r12 + r21) / s, (r02 - r20) / s
    else:
        s = 2 * math.sqrt(1 + r22 - r00 - r11)
        x, y, z, w = (r02 + r20) / s, (r12 + r21) / s, s / 4, (r10 - r01) / s
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    norm = -norm if w < 0 else norm
    return np.array([x / norm, y / norm, z / norm, w / norm])


def rotation_to_quaternion(rot: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) to unit quaternions (N, 4), x y z w, w >= 0."""
    quat = Rotation.from_matrix(rot).as_quat()
    return np.where(quat[:, 3:4] < 0, -quat, quat)


_SKEW = (np.array([2, 0, 1]), np.array([1, 2, 0]))


def rotation_log(rot: np.ndarray) -> np.ndarray:
    """Rotation vectors (N, 3) [rad] of rotation matrices (N, 3, 3) (the SO(3) logarithm)."""
    v = 0.5 * (rot[:, _SKEW[0], _SKEW[1]] - rot[:, _SKEW[1], _SKEW[0]])
    # sums by hand, not np.einsum (whose first call is dear when the caches are cold)
    sin = np.sqrt(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1] + v[:, 2] * v[:, 2])
    # np.minimum(np.maximum()) as np.clip, without its wrapper
    cos = np.minimum(np.maximum((rot[:, 0, 0] + rot[:, 1, 1] + rot[:, 2, 2] - 1) / 2, -1.0),
                     1.0)
    angle = np.arctan2(sin, cos)
    out = v * np.divide(angle, sin, out=np.ones_like(sin), where=sin > 1e-9)[:, None]
    near_pi = (sin < 1e-6) & (cos < 0)
    if near_pi.any():  # the skew part vanishes at pi: take the axis from R + I
        out[near_pi] = Rotation.from_matrix(rot[near_pi]).as_rotvec()
    return out


def rotation_angle(target: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """Angles [rad] between rotations, |log(target^T rot)|: (3, 3) or (N, 3, 3) against (N, 3, 3).

    A single ``target`` is compared with every row of ``rot``; N targets row by row.
    """
    cos = ((target * rot).sum(axis=(1, 2)) - 1) / 2
    return np.arccos(np.clip(cos, -1.0, 1.0))
