"""Compiled forward kinematics and geometric Jacobians of a revolute serial chain.

The chain is one array ``frames`` (n + 2, 4, 3) (:func:`chain_frames`): rows 0-2 of
``frames[i]`` are joint ``i``'s rotation in its parent joint's frame and row 3 its translation
[m]; ``frames[n]`` is the base (the world in the base frame), ``frames[n + 1]`` the tip in the
last joint's frame. Every joint turns about its own z axis
(:class:`~sik_ros.kinematics.chain.SerialChain`),
so a joint's rotation mixes two columns of the running rotation. The kernels keep the running
placement in scalars (no allocation per joint) and write into arrays the caller owns.
"""

import math

from numba import njit
import numpy as np

from sik_ros.kernels._cache import CACHE


def chain_frames(chain) -> np.ndarray:
    """The kernels' ``frames`` array (n + 2, 4, 3) of a chain (C-contiguous float64).

    ``chain``: a :class:`~sik_ros.kinematics.chain.SerialChain` (its joint, base and tip
    rotations and translations).
    """
    n = chain.dof
    frames = np.zeros((n + 2, 4, 3))
    frames[:n, :3] = chain.joint_rotations
    frames[:n, 3] = chain.joint_translations
    frames[n, :3], frames[n, 3] = chain.base_rotation, chain.base_translation
    frames[n + 1, :3], frames[n + 1, 3] = chain.tip_rotation, chain.tip_translation
    return np.ascontiguousarray(frames)


@njit(cache=CACHE, nogil=True)
def place(frames, q, p, r, jac, with_jac):  # pragma: no cover (compiled)
    """Tip position ``p`` (3,) [m], rotation ``r`` (3, 3) and, ``with_jac``, the Jacobian.

    ``jac`` (6, n): the tip's linear [m/rad] then angular velocity per joint velocity, in the
    base frame, taken at the tip (Pinocchio's ``LOCAL_WORLD_ALIGNED``).
    """
    n = q.shape[0]
    b = frames[n]
    r00, r01, r02 = b[0, 0], b[0, 1], b[0, 2]
    r10, r11, r12 = b[1, 0], b[1, 1], b[1, 2]
    r20, r21, r22 = b[2, 0], b[2, 1], b[2, 2]
    px, py, pz = b[3, 0], b[3, 1], b[3, 2]
    for i in range(n):
        f = frames[i]
        t0, t1, t2 = f[3, 0], f[3, 1], f[3, 2]
        px += r00 * t0 + r01 * t1 + r02 * t2
        py += r10 * t0 + r11 * t1 + r12 * t2
        pz += r20 * t0 + r21 * t1 + r22 * t2
        a00 = r00 * f[0, 0] + r01 * f[1, 0] + r02 * f[2, 0]
        a01 = r00 * f[0, 1] + r01 * f[1, 1] + r02 * f[2, 1]
        a02 = r00 * f[0, 2] + r01 * f[1, 2] + r02 * f[2, 2]
        a10 = r10 * f[0, 0] + r11 * f[1, 0] + r12 * f[2, 0]
        a11 = r10 * f[0, 1] + r11 * f[1, 1] + r12 * f[2, 1]
        a12 = r10 * f[0, 2] + r11 * f[1, 2] + r12 * f[2, 2]
        a20 = r20 * f[0, 0] + r21 * f[1, 0] + r22 * f[2, 0]
        a21 = r20 * f[0, 1] + r21 * f[1, 1] + r22 * f[2, 1]
        a22 = r20 * f[0, 2] + r21 * f[1, 2] + r22 * f[2, 2]
        c, s = math.cos(q[i]), math.sin(q[i])
        r00, r01, r02 = c * a00 + s * a01, c * a01 - s * a00, a02
        r10, r11, r12 = c * a10 + s * a11, c * a11 - s * a10, a12
        r20, r21, r22 = c * a20 + s * a21, c * a21 - s * a20, a22
        if with_jac:
            jac[0, i], jac[1, i], jac[2, i] = px, py, pz  # the joint's origin, for now
            jac[3, i], jac[4, i], jac[5, i] = r02, r12, r22
    t = frames[n + 1]
    px += r00 * t[3, 0] + r01 * t[3, 1] + r02 * t[3, 2]
    py += r10 * t[3, 0] + r11 * t[3, 1] + r12 * t[3, 2]
    pz += r20 * t[3, 0] + r21 * t[3, 1] + r22 * t[3, 2]
    p[0], p[1], p[2] = px, py, pz
    for k in range(3):
        r[0, k] = r00 * t[0, k] + r01 * t[1, k] + r02 * t[2, k]
        r[1, k] = r10 * t[0, k] + r11 * t[1, k] + r12 * t[2, k]
        r[2, k] = r20 * t[0, k] + r21 * t[1, k] + r22 * t[2, k]
    if with_jac:
        for i in range(n):
            dx, dy, dz = px - jac[0, i], py - jac[1, i], pz - jac[2, i]
            ax, ay, az = jac[3, i], jac[4, i], jac[5, i]
            jac[0, i] = ay * dz - az * dy
            jac[1, i] = az * dx - ax * dz
            jac[2, i] = ax * dy - ay * dx


#: The kernels' argument types (C-contiguous float64 arrays), compiled when this module loads.
F1, F2, F3 = 'float64[::1]', 'float64[:, ::1]', 'float64[:, :, ::1]'


@njit(f'void({F3}, {F2}, {F2}, {F3})', cache=CACHE, nogil=True)
def fk_many(frames, q, p, r):  # pragma: no cover (compiled)
    """Tip positions ``p`` (M, 3) [m] and rotations ``r`` (M, 3, 3) of ``q`` (M, n) [rad]."""
    dummy = np.empty((6, 0))
    for k in range(q.shape[0]):
        place(frames, q[k], p[k], r[k], dummy, False)


@njit(f'void({F3}, {F2}, {F2}, {F3}, {F3})', cache=CACHE, nogil=True)
def jac_many(frames, q, p, r, jac):  # pragma: no cover (compiled)
    """:func:`fk_many` and the Jacobians ``jac`` (M, 6, n) (see :func:`place`)."""
    for k in range(q.shape[0]):
        place(frames, q[k], p[k], r[k], jac[k], True)


@njit(cache=CACHE, nogil=True)
def rotation_error(goal, r, out):  # pragma: no cover (compiled)
    """``out`` (3,): the rotation vector log(goal r^T) [rad]; returns its norm [rad]."""
    g = goal
    m00 = g[0, 0] * r[0, 0] + g[0, 1] * r[0, 1] + g[0, 2] * r[0, 2]
    m01 = g[0, 0] * r[1, 0] + g[0, 1] * r[1, 1] + g[0, 2] * r[1, 2]
    m02 = g[0, 0] * r[2, 0] + g[0, 1] * r[2, 1] + g[0, 2] * r[2, 2]
    m10 = g[1, 0] * r[0, 0] + g[1, 1] * r[0, 1] + g[1, 2] * r[0, 2]
    m11 = g[1, 0] * r[1, 0] + g[1, 1] * r[1, 1] + g[1, 2] * r[1, 2]
    m12 = g[1, 0] * r[2, 0] + g[1, 1] * r[2, 1] + g[1, 2] * r[2, 2]
    m20 = g[2, 0] * r[0, 0] + g[2, 1] * r[0, 1] + g[2, 2] * r[0, 2]
    m21 = g[2, 0] * r[1, 0] + g[2, 1] * r[1, 1] + g[2, 2] * r[1, 2]
    m22 = g[2, 0] * r[2, 0] + g[2, 1] * r[2, 1] + g[2, 2] * r[2, 2]
    vx, vy, vz = 0.5 * (m21 - m12), 0.5 * (m02 - m20), 0.5 * (m10 - m01)
    sin = math.sqrt(vx * vx + vy * vy + vz * vz)
    cos = min(max((m00 + m11 + m22 - 1.0) * 0.5, -1.0), 1.0)
    angle = math.atan2(sin, cos)
    if sin < 1e-6 and cos < 0.0:
        # near pi the skew part vanishes: the axis from (m + I) / 2 = a a^T, its largest
        # diagonal entry's column
        if m00 >= m11 and m00 >= m22:
            top = math.sqrt(max((m00 + 1.0) * 0.5, 1e-300))
            ax, ay, az = top, (m10 + m01) * 0.25 / top, (m20 + m02) * 0.25 / top
        elif m11 >= m22:
            top = math.sqrt(max((m11 + 1.0) * 0.5, 1e-300))
            ax, ay, az = (m01 + m10) * 0.25 / top, top, (m21 + m12) * 0.25 / top
        else:
            top = math.sqrt(max((m22 + 1.0) * 0.5, 1e-300))
            ax, ay, az = (m02 + m20) * 0.25 / top, (m12 + m21) * 0.25 / top, top
        if ax * vx + ay * vy + az * vz < 0.0:
            ax, ay, az = -ax, -ay, -az
        out[0], out[1], out[2] = ax * angle, ay * angle, az * angle
        return angle
    scale = angle / sin if sin > 1e-9 else 1.0
    out[0], out[1], out[2] = vx * scale, vy * scale, vz * scale
    return sin * scale


@njit(f'void({F3}, {F2}, {F2}, float64, float64)', cache=CACHE, nogil=True)
def align_last_many(frames, q, goal, lower, upper):  # pragma: no cover (compiled)
    """Turn the last joint of each row of ``q`` (M, n) towards the tip rotation ``goal``.

    In place, within ``lower``..``upper``; ``goal`` is (3, 3).
    Every joint turns about its own z axis: with ``a`` the last joint's frame at zero and
    ``B`` the fixed tip rotation, ``a Rz(t) B = goal`` is best met by the angle about z of
    ``Rz(t) ~ B R0^T goal B^T``, where ``R0 = a B`` is the tip rotation at zero.
    """
    n = q.shape[1]
    b = frames[n + 1]
    p, r0 = np.empty(3), np.empty((3, 3))
    dummy = np.empty((6, 0))
    c, m = np.empty((3, 3)), np.empty((2, 2))
    for k in range(q.shape[0]):
        q[k, n - 1] = 0.0
        place(frames, q[k], p, r0, dummy, False)
        # m = B (R0^T goal) B^T: only its top-left 2 x 2 block is needed
        for i in range(3):
            for j in range(3):
                c[i, j] = r0[0, i] * goal[0, j] + r0[1, i] * goal[1, j] + r0[2, i] * goal[2, j]
        for i in range(2):
            for j in range(2):
                s = 0.0
                for u in range(3):
                    for v in range(3):
                        s += b[i, u] * c[u, v] * b[j, v]
                m[i, j] = s
        theta = math.atan2(m[1, 0] - m[0, 1], m[0, 0] + m[1, 1])
        q[k, n - 1] = min(max(theta, lower), upper)


@njit(cache=CACHE, nogil=True)
def _det6(a):  # pragma: no cover (compiled)
    """Determinant of a 6 x 6 matrix ``a`` (overwritten), by elimination with partial pivoting."""
    det = 1.0
    n = a.shape[0]
    for c in range(n):
        p = c
        for r in range(c + 1, n):
            if abs(a[r, c]) > abs(a[p, c]):
                p = r
        if a[p, c] == 0.0:
            return 0.0
        if p != c:
            for k in range(n):
                a[c, k], a[p, k] = a[p, k], a[c, k]
            det = -det
        det *= a[c, c]
        for r in range(c + 1, n):
            f = a[r, c] / a[c, c]
            for k in range(c + 1, n):
                a[r, k] -= f * a[c, k]
    return det


@njit(f'int64[::1]({F3}, {F2}, int64[::1], float64[::1], boolean)', cache=CACHE, nogil=True)
def branch_codes(frames, q, joints, centres, determinant):  # pragma: no cover (compiled)
    """Each row's branch code (M,) of configurations ``q`` (M, n) [rad].

    Bit k: ``sin(q[joints[k]] - centres[k]) > 0``; with ``determinant`` (a 6 x 6 Jacobian),
    the next bit: the Jacobian's determinant is positive
    (:class:`~sik_ros.kinematics.branches.BranchSigns`).
    """
    m, n = q.shape
    out = np.zeros(m, dtype=np.int64)
    p, r = np.empty(3), np.empty((3, 3))
    jac = np.empty((6, n))
    for i in range(m):
        code = 0
        for k in range(joints.shape[0]):
            if math.sin(q[i, joints[k]] - centres[k]) > 0.0:
                code |= 1 << k
        if determinant:
            place(frames, q[i], p, r, jac, True)
            if _det6(jac) > 0.0:
                code |= 1 << joints.shape[0]
        out[i] = code
    return out


@njit(cache=CACHE, nogil=True)
def null_vector7(jac, minor, v):  # pragma: no cover (compiled)
    """``v`` (7,): the unit null vector of a 6 x 7 Jacobian ``jac``; False if (nearly) singular.

    The null vector of a full-rank 6 x 7 matrix has the signed 6 x 6 minors as its entries
    (the generalised cross product); ``minor`` (6, 6) is work space. The minors scale as the
    sixth power of the entries: relative to that, too small a vector means a rank below 6
    (the caller then takes the null space from an SVD, or stops).
    """
    norm = 0.0
    scale = 0.0
    for r in range(6):
        for c in range(7):
            scale = max(scale, abs(jac[r, c]))
    for i in range(7):
        for r in range(6):
            c2 = 0
            for c in range(7):
                if c != i:
                    minor[r, c2] = jac[r, c]
                    c2 += 1
        d = _det6(minor)
        v[i] = -d if i % 2 else d
        norm += v[i] * v[i]
    if norm <= (1e-9 * scale ** 6) ** 2:
        return False
    norm = math.sqrt(norm)
    for i in range(7):
        v[i] /= norm
    return True


@njit(f'boolean[::1]({F3}, {F2})', cache=CACHE, nogil=True)
def null_directions(jac, out):  # pragma: no cover (compiled)
    """Unit vectors spanning the null spaces of 6 x 7 Jacobians ``jac`` (M, 6, 7) into ``out``.

    Each row's by :func:`null_vector7`. Returns, per row, whether it was found: False where
    the Jacobian is (nearly) singular, whose null space the caller takes from an SVD.
    """
    m = jac.shape[0]
    ok = np.ones(m, dtype=np.bool_)
    minor = np.empty((6, 6))
    for k in range(m):
        ok[k] = null_vector7(jac[k], minor, out[k])
    return ok
