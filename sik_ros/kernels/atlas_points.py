"""Compiled reading of a pose's atlas (:mod:`sik_ros.kernels.atlas`): its points and pieces.

- :func:`spread_points`: points far apart on each piece;
- :func:`atlas_pieces`: the piece of any solution.
"""

from numba import njit
import numpy as np

from sik_ros.kernels._cache import CACHE
from sik_ros.kernels.angles import angle_distance


@njit('int64(float64[:, ::1], int64[::1], int64, float64[:, ::1], int64[::1], boolean[::1], '
      'float64, int64, float64[:, ::1], int64[::1])', cache=CACHE, nogil=True)
def spread_points(points, piece, count, q, row_piece, periodic, spacing, per_piece, out,
                  out_piece):  # pragma: no cover (compiled)
    """Points of the atlas far apart on each piece, for solutions the known ones are not.

    Of the first ``count`` recorded ``points`` (:func:`trace_atlas`), a piece no row of ``q``
    lies on first gets its middle recorded point; then, of every piece in turn, the point
    farthest from its rows and the points taken on it, while at least ``spacing`` [rad] from
    them, up to ``per_piece`` per piece. Written to ``out`` (K, 7), their pieces to ``out_piece``.

    Returns:
        how many points were written (at most K).
    """
    k = 0
    taken = np.zeros(count + 1, dtype=np.int64)  # per piece (numbers are recorded indices)
    known = np.zeros(count + 1, dtype=np.bool_)
    for i in range(q.shape[0]):
        if 0 <= row_piece[i] <= count:
            known[row_piece[i]] = True
    first = np.full(count + 1, -1)
    last = np.full(count + 1, -1)
    for j in range(count):
        f = piece[j]
        if first[f] < 0:
            first[f] = j
        last[f] = j
    for f in range(count + 1):  # the middle of each piece no row lies on
        if first[f] < 0 or known[f] or k >= out.shape[0]:
            continue
        mid = (first[f] + last[f]) // 2
        while piece[mid] != f:
            mid += 1
        out[k] = points[mid]
        out_piece[k] = f
        taken[f] += 1
        k += 1
    # then the farthest point of a piece from its rows and the points taken, in turn: the
    # points spread over the whole piece
    near = np.full(count, np.inf)
    for j in range(count):
        for i in range(q.shape[0]):
            if row_piece[i] == piece[j]:
                near[j] = min(near[j], angle_distance(points[j], q[i], periodic))
        for e in range(k):
            if out_piece[e] == piece[j]:
                near[j] = min(near[j], angle_distance(points[j], out[e], periodic))
    while k < out.shape[0]:
        best, far = -1, spacing
        for j in range(count):
            if near[j] >= far and taken[piece[j]] < per_piece:
                best, far = j, near[j]
        if best < 0:
            break
        f = piece[best]
        out[k] = points[best]
        out_piece[k] = f
        taken[f] += 1
        k += 1
        for j in range(count):
            if piece[j] == f:
                near[j] = min(near[j], angle_distance(points[j], points[best], periodic))
    return k


@njit('int64[::1](float64[:, ::1], int64[::1], int64, float64[:, ::1], boolean[::1], float64)',
      cache=CACHE, nogil=True)
def atlas_pieces(points, piece, count, q, periodic, link):  # pragma: no cover (compiled)
    """The piece of each row of ``q``: its nearest recorded point's within ``link``, or -1."""
    out = np.full(q.shape[0], -1)
    for i in range(q.shape[0]):
        best = link
        for j in range(count):
            d = angle_distance(q[i], points[j], periodic)
            if d < best:
                best = d
                out[i] = piece[j]
                if d < 0.1 * link:
                    break
    return out
