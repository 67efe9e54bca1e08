"""Compiled greedy choices among a few hundred rows: far-apart subsets, distinct rows, unions.

The first two walk the rows in order and compare each with the ones chosen so far, one call
instead of a NumPy call per pick; distances are plain Euclidean ones (L2 over the columns
compared). :func:`root` and :func:`union` are a union-find forest (families, pieces).
"""

import math

from numba import njit
import numpy as np

from sik_ros.kernels._cache import CACHE
from sik_ros.kernels.angles import PER_TURN, TURN

#: :func:`distinct_rows`' ``groups`` for rows in no group.
NO_GROUPS = np.empty(0, dtype=np.int64)


@njit('int64[::1](float64[:, ::1], int64, int64, float64, int64, float64)', cache=CACHE,
      nogil=True)
def farthest_rows(points, k, first, spacing, at_least, same):  # pragma: no cover (compiled)
    """Indices of up to ``k`` rows chosen greedily far apart, ``first`` first.

    With ``spacing`` > 0 the choice stops once ``at_least`` rows are chosen and the farthest
    row left is within ``spacing`` of a chosen one, or when it is within ``same`` of one.
    """
    n, d = points.shape
    dist = np.empty(n)
    chosen = np.empty(min(k, n), dtype=np.int64)
    chosen[0] = first
    count = 1
    for j in range(n):
        s = 0.0
        for c in range(d):
            v = points[j, c] - points[first, c]
            s += v * v
        dist[j] = math.sqrt(s)
    while count < min(k, n):
        i = 0
        for j in range(1, n):
            if dist[j] > dist[i]:
                i = j
        if spacing > 0.0 and (dist[i] <= same or (dist[i] < spacing and count >= at_least)):
            break
        chosen[count] = i
        count += 1
        for j in range(n):
            s = 0.0
            for c in range(d):
                v = points[j, c] - points[i, c]
                s += v * v
            s = math.sqrt(s)
            if s < dist[j]:
                dist[j] = s
    return chosen[:count].copy()


@njit('boolean[::1](float64[:, ::1], float64, int64, boolean[::1], int64[::1])', cache=CACHE,
      nogil=True)
def distinct_rows(q, threshold, cols, periodic, groups):  # pragma: no cover (compiled)
    """Keep-mask of rows (in order) at least ``threshold`` from every earlier kept one [rad].

    Over the first ``cols`` columns; a ``periodic`` joint's difference is taken at its nearest
    2 pi turn. ``groups`` (M,): rows of two different groups (both >= 0: two posture
    families) are never one; -1, or an empty array, compares with every row.
    """
    m = q.shape[0]
    keep = np.zeros(m, dtype=np.bool_)
    t2 = threshold * threshold
    grouped = groups.shape[0] == m
    for i in range(m):
        ok = True
        for j in range(i):
            if not keep[j]:
                continue
            if grouped and groups[i] >= 0 and groups[j] >= 0 and groups[i] != groups[j]:
                continue
            s = 0.0
            for c in range(cols):
                v = q[i, c] - q[j, c]
                if periodic[c]:
                    v -= TURN * np.rint(v * PER_TURN)
                s += v * v
            if s < t2:
                ok = False
                break
        keep[i] = ok
    return keep


@njit('void(int64[::1], float64[::1], int64, int64, float64)', cache=CACHE, nogil=True)
def _insert(rows, keys, count, row, key):  # pragma: no cover (compiled)
    """Put ``row`` with ``key`` into the first ``count`` rows sorted by key, after equal keys.

    An insertion sort's step: a stable order, as NumPy's stable sort gives.
    """
    j = count
    while j > 0 and keys[j - 1] > key:
        rows[j], keys[j] = rows[j - 1], keys[j - 1]
        j -= 1
    rows[j], keys[j] = row, key


@njit(cache=CACHE, nogil=True)
def margin_cost(q, lower, upper):  # pragma: no cover (compiled)
    """The default ranking's cost of one configuration ``q`` (n,): closeness to the limits.

    1 minus the smallest of the joints' margins to a limit, each over half its range (0 in
    the middle of every range, 1 at a limit). The one formula:
    :class:`~sik_ros.solver.objectives.JointLimitMargin` and :func:`exact_by_margin` call it.
    """
    margin = np.inf
    for c in range(q.shape[0]):
        half = (upper[c] - lower[c]) / 2
        margin = min(margin, min(q[c] - lower[c], upper[c] - q[c]) / half)
    return 1.0 - margin


@njit('float64[::1](float64[:, ::1], float64[::1], float64[::1])', cache=CACHE, nogil=True)
def margin_costs(q, lower, upper):  # pragma: no cover (compiled)
    """(M,) :func:`margin_cost` of each row of ``q`` (M, n)."""
    out = np.empty(q.shape[0])
    for i in range(q.shape[0]):
        out[i] = margin_cost(q[i], lower, upper)
    return out


@njit('Tuple((int64[::1], float64[::1]))(float64[:, ::1], float64[::1], float64[::1], '
      'float64, float64, float64, float64, float64[::1], float64[::1])', cache=CACHE, nogil=True)
def exact_by_margin(q, perr, oerr, position_tolerance, orientation_tolerance, weight,
                    threshold, lower, upper):  # pragma: no cover (compiled)
    """The exact rows, one per posture, ordered by closeness to the joint limits.

    Exact: ``perr`` and ``oerr`` within the tolerances. Taken by their goal error (``perr +
    weight * oerr``, ties in row order), a row within ``threshold`` [rad] of one taken before
    is left out; the rest are ordered by the default ranking's cost, :func:`margin_cost`
    (ties in the previous order).

    Returns:
        the rows' indices (K,) and their costs (K,).
    """
    m, n = q.shape
    rows = np.empty(m, dtype=np.int64)
    score = np.empty(m)
    k = 0
    for i in range(m):
        if perr[i] <= position_tolerance and oerr[i] <= orientation_tolerance:
            _insert(rows, score, k, i, perr[i] + weight * oerr[i])
            k += 1
    keep = distinct_rows(q[rows[:k]], threshold, n, np.zeros(n, dtype=np.bool_),
                         np.empty(0, dtype=np.int64))
    out = np.empty(k, dtype=np.int64)
    cost = np.empty(k)
    kept = 0
    for a in range(k):
        if not keep[a]:
            continue
        i = rows[a]
        _insert(out, cost, kept, i, margin_cost(q[i], lower, upper))
        kept += 1
    return out[:kept].copy(), cost[:kept].copy()


@njit(cache=CACHE, nogil=True)
def root(parent, i):  # pragma: no cover (compiled)
    """The root of ``i`` in the union-find forest ``parent`` (paths halved)."""
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit(cache=CACHE, nogil=True)
def roots(parent):  # pragma: no cover (compiled)
    """Each element's root."""
    out = np.empty(parent.shape[0], dtype=np.int64)
    for i in range(parent.shape[0]):
        out[i] = root(parent, i)
    return out


@njit(cache=CACHE, nogil=True)
def union(parent, a, b):  # pragma: no cover (compiled)
    """Join the sets of ``a`` and ``b``; the smaller root stays the root."""
    ra, rb = root(parent, a), root(parent, b)
    if ra < rb:
        parent[rb] = ra
    elif rb < ra:
        parent[ra] = rb
