"""Compiled look-ups in the posture-index table's cells: the nearest cells, the best-oriented rows.

The table's cells are boxes of a regular grid (edge ``cell``), each with a centre (the mean tip
position of its rows) inside its box. :class:`CellGrid` keeps, per grid box, the cells whose
centres lie in it, so the ``k`` centres nearest a point are found by visiting boxes in growing
shells around the point's box until the ``k``-th nearest found is closer than any box not yet
visited: the KD-tree's answer, in one compiled call. A point farther than a few shells from
every centre (a goal out of reach) is left to the KD-tree.
"""

import math
from typing import Optional

from numba import njit
import numpy as np

from sik_ros.kernels._cache import CACHE

#: Shells of boxes searched around a point before the KD-tree takes over, and the most boxes
#: a grid may have (a larger workspace at a finer cell keeps the KD-tree alone).
MAX_SHELLS = 6
MAX_BOXES = 8_000_000


class CellGrid:
    """The cells of a table by grid box, for :func:`nearest_cells`.

    Attributes:
        origin: the lowest box's integer coordinates (3,) int64.
        dims: boxes along each axis (3,) int64.
        starts: per box (flattened, x major), where its cells begin in ``order`` (B + 1,) int64.
        order: cell numbers sorted by box (C,) int64.
    """

    def __init__(self, origin: np.ndarray, dims: np.ndarray, starts: np.ndarray,
                 order: np.ndarray):
        self.origin, self.dims, self.starts, self.order = origin, dims, starts, order

    @classmethod
    def build(cls, centers: np.ndarray, cell: float) -> Optional['CellGrid']:
        """The grid of ``centers`` (C, 3) [m] in boxes of edge ``cell`` [m], or None if too big."""
        if len(centers) == 0:
            return None
        box = np.floor(centers / cell).astype(np.int64)
        origin = box.min(axis=0)
        dims = box.max(axis=0) - origin + 1
        if int(np.prod(dims)) > MAX_BOXES:
            return None
        flat = np.ravel_multi_index(tuple((box - origin).T), tuple(dims))
        order = np.argsort(flat, kind='stable').astype(np.int64)
        counts = np.bincount(flat, minlength=int(np.prod(dims)))
        starts = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        return cls(origin.astype(np.int64), dims.astype(np.int64), starts, order)


@njit('int64[::1](float64[::1], float64[:, ::1], float64, int64[::1], int64[::1], int64[::1], '
      'int64[::1], int64, int64)', cache=CACHE, nogil=True)
def nearest_cells(point, centers, cell, origin, dims, starts, order, k,
                  max_shells):  # pragma: no cover (compiled)
    """The ``k`` cells whose centres are nearest ``point``, nearest first.

    Empty when the search would need more than ``max_shells`` shells (the caller asks the
    KD-tree).
    """
    k = min(k, centers.shape[0])
    best_d = np.full(k, np.inf)
    best_c = np.full(k, -1, dtype=np.int64)
    found = 0
    g = np.empty(3, dtype=np.int64)
    for a in range(3):
        g[a] = int(math.floor(point[a] / cell)) - origin[a]
    for r in range(max_shells + 1):
        covers = True
        for a in range(3):
            if g[a] - r > 0 or g[a] + r < dims[a] - 1:
                covers = False
        for i in range(max(g[0] - r, 0), min(g[0] + r, dims[0] - 1) + 1):
            for j in range(max(g[1] - r, 0), min(g[1] + r, dims[1] - 1) + 1):
                for m in range(max(g[2] - r, 0), min(g[2] + r, dims[2] - 1) + 1):
                    if max(abs(i - g[0]), abs(j - g[1]), abs(m - g[2])) != r:
                        continue  # an inner box, visited in an earlier shell
                    b = (i * dims[1] + j) * dims[2] + m
                    for s in range(starts[b], starts[b + 1]):
                        c = order[s]
                        d = 0.0
                        for a in range(3):
                            v = centers[c, a] - point[a]
                            d += v * v
                        d = math.sqrt(d)
                        if found == k and d >= best_d[k - 1]:
                            continue
                        p = min(found, k - 1)
                        while p > 0 and best_d[p - 1] > d:
                            best_d[p], best_c[p] = best_d[p - 1], best_c[p - 1]
                            p -= 1
                        best_d[p], best_c[p] = d, c
                        found = min(found + 1, k)
        if covers:
            return best_c[:found].copy()
        # every box not yet visited lies outside the block of shells 0..r
        bound = np.inf
        for a in range(3):
            low = point[a] - (g[a] + origin[a] - r) * cell
            high = (g[a] + origin[a] + r + 1) * cell - point[a]
            bound = min(bound, low, high)
        if found == k and best_d[k - 1] <= bound - 1e-9:
            return best_c.copy()
    return np.empty(0, dtype=np.int64)


@njit('int64[::1](int64[::1], int64[::1])', cache=CACHE, nogil=True)
def cell_rows(cells, offsets):  # pragma: no cover (compiled)
    """The table rows of ``cells``, end to end in their order."""
    total = 0
    for c in cells:
        total += offsets[c + 1] - offsets[c]
    rows = np.empty(total, dtype=np.int64)
    n = 0
    for c in cells:
        for r in range(offsets[c], offsets[c + 1]):
            rows[n] = r
            n += 1
    return rows


@njit('int64[::1](int64[::1], float32[:, ::1], float32[::1], int64)', cache=CACHE, nogil=True)
def best_oriented(rows, orientations, quaternion, count):  # pragma: no cover (compiled)
    """The ``count`` of ``rows`` whose orientations are nearest ``quaternion``, nearest first.

    Nearest: the largest ``|q . quaternion|``; ties in the order of ``rows``.
    """
    n = rows.shape[0]
    count = min(count, n)
    best_v = np.empty(count, dtype=np.float32)
    best_i = np.empty(count, dtype=np.int64)
    found = 0
    for i in range(n):
        r = rows[i]
        v = np.float32(0.0)
        for a in range(4):
            v += orientations[r, a] * quaternion[a]
        v = abs(v)
        if found == count and v <= best_v[count - 1]:
            continue
        p = min(found, count - 1)
        while p > 0 and best_v[p - 1] < v:
            best_v[p], best_i[p] = best_v[p - 1], best_i[p - 1]
            p -= 1
        best_v[p], best_i[p] = v, r
        found = min(found + 1, count)
    return best_i
