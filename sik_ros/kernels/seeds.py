"""The seed table's look-up in compiled calls: a goal's key, then its starts from the table.

:mod:`sik_ros.tables.seed_table` holds what they compute and why; here are the loops, so that a
look-up is two calls, not some twenty NumPy calls on arrays of a hundred rows.
"""

import math

from numba import njit
import numpy as np

from sik_ros.kernels._cache import CACHE
from sik_ros.kernels.angles import LIMIT_SLACK, turn_once
from sik_ros.kernels.kdtree import nearest_rows, TREE_TYPES
from sik_ros.kernels.sets import farthest_rows

#: The fields of :func:`table_starts`'s ``reals`` and ``ints``, in order: the goal's azimuth
#: [rad], the first joint's limits [rad], the look-up's slack, the starts' spacing and the
#: distance under which two are one; whether the first joint is turned to the azimuth, the
#: rows wanted, the first look-up's size, the most rows looked up, the starts asked and the
#: fewest kept.
STARTS_REALS = ('azimuth', 'lower', 'upper', 'eps', 'spacing', 'same')
STARTS_INTS = ('turn_first', 'k', 'wanted', 'most', 'count', 'at_least')
S_AZIMUTH, S_LOWER, S_UPPER, S_EPS, S_SPACING, S_SAME = range(len(STARTS_REALS))
S_TURN_FIRST, S_K, S_WANTED, S_MOST, S_COUNT, S_AT_LEAST = range(len(STARTS_INTS))


@njit('Tuple((float64[::1], float64))(float64[::1], float64[:, ::1], float64[::1], '
      'float64[::1], float64[::1], float64)', cache=CACHE, nogil=True)
def axis_key(origin, rot, inverse, position, quaternion, scale):  # pragma: no cover
    """A goal pose's key in the first joint's frame turned to azimuth 0, and its azimuth [rad].

    ``origin``, ``rot``: the frame (its z the first joint's axis); ``inverse``: its inverse
    rotation as a quaternion (x y z w). The key: the turned position [m], then ``scale`` times
    the turned quaternion with w >= 0.
    """
    x, y, z = position[0] - origin[0], position[1] - origin[1], position[2] - origin[2]
    px = x * rot[0, 0] + y * rot[1, 0] + z * rot[2, 0]
    py = x * rot[0, 1] + y * rot[1, 1] + z * rot[2, 1]
    pz = x * rot[0, 2] + y * rot[1, 2] + z * rot[2, 2]
    cx, cy, cz, cw = inverse[0], inverse[1], inverse[2], inverse[3]
    qx, qy, qz, qw = quaternion[0], quaternion[1], quaternion[2], quaternion[3]
    ax = cw * qx + cx * qw + cy * qz - cz * qy
    ay = cw * qy - cx * qz + cy * qw + cz * qx
    az = cw * qz + cx * qy - cy * qx + cz * qw
    aw = cw * qw - cx * qx - cy * qy - cz * qz
    azimuth = math.atan2(py, px)
    c, s = math.cos(-azimuth), math.sin(-azimuth)
    sa, ca = math.sin(-azimuth / 2), math.cos(-azimuth / 2)
    key = np.empty(7)
    key[0], key[1], key[2] = c * px - s * py, s * px + c * py, pz
    key[3], key[4] = ca * ax - sa * ay, ca * ay + sa * ax
    key[5], key[6] = ca * az + sa * aw, ca * aw - sa * az
    sign = -scale if key[6] < 0 else scale  # as the table's
    for i in range(3, 7):
        key[i] *= sign
    return key, azimuth


@njit('float64[:, ::1](' + TREE_TYPES + ', float64[:, ::1], float64[::1], float64[::1], '
      'float64[::1], int64[::1])', cache=CACHE, nogil=True)
def table_starts(points, nodes, split, low, high, depth, columns, base_q, key, other, reals,
                 ints):  # pragma: no cover (compiled)
    """Up to ``count`` of the ``k`` table rows nearest a key, far apart (the table's starts).

    ``reals`` and ``ints``: the values named by :data:`STARTS_REALS` and :data:`STARTS_INTS`
    (below by their names). ``base_q``: the table's configurations in the tree's leaf order.
    With ``turn_first``, the
    rows' first joints are turned by ``azimuth`` (a whole turn added or taken off where that
    brings them within ``lower``..``upper``), rows that still do not fit are passed over, and
    the look-up goes further (``wanted`` doubled) until ``k`` fit, at most to the ``most``
    nearest rows (fewer than ``k`` then: the rows beyond are far from the key, and a look-up
    that far costs a large share of the table). The far-apart ones are chosen
    by :func:`farthest_rows` over the joints' cosines and sines (``spacing``, ``at_least``,
    ``same``), the nearest row first.
    """
    azimuth, lower, upper = reals[S_AZIMUTH], reals[S_LOWER], reals[S_UPPER]
    eps, spacing, same = reals[S_EPS], reals[S_SPACING], reals[S_SAME]
    turn_first, k, wanted = ints[S_TURN_FIRST] != 0, ints[S_K], ints[S_WANTED]
    most, count, at_least = ints[S_MOST], ints[S_COUNT], ints[S_AT_LEAST]
    total, n = points.shape[0], base_q.shape[1]
    while True:
        rows, _ = nearest_rows(points, nodes, split, low, high, depth, columns, key, other,
                               wanted, eps)
        q = np.empty((min(rows.shape[0], k), n))
        m = 0
        for i in range(rows.shape[0]):
            if m == q.shape[0]:
                break
            v = base_q[rows[i], 0]
            if turn_first:
                v += azimuth
                v = turn_once(v, lower - LIMIT_SLACK, upper + LIMIT_SLACK)
                if v < lower - LIMIT_SLACK or v > upper + LIMIT_SLACK:
                    continue
                v = min(max(v, lower), upper)
            for j in range(n):
                q[m, j] = base_q[rows[i], j]
            q[m, 0] = v
            m += 1
        if not turn_first or m >= k or wanted >= min(total, most):
            break
        wanted = min(2 * wanted, total, most)
    if m == 0 or count < 1:
        return np.empty((0, n))
    ends = np.empty((m, 2 * n))
    for i in range(m):
        for j in range(n):
            ends[i, j], ends[i, n + j] = math.cos(q[i, j]), math.sin(q[i, j])
    pick = farthest_rows(ends, count, 0, spacing, at_least, same)
    out = np.empty((pick.shape[0], n))
    for i in range(pick.shape[0]):
        for j in range(n):
            out[i, j] = q[pick[i], j]
    return out
