"""Distances between rows and far-apart subsets of them (tables, candidates, seed tables)."""

from typing import Optional

import numpy as np
from scipy.spatial.distance import cdist

from sik_ros.kernels import as_arg
from sik_ros.kernels.sets import farthest_rows

#: Rows up to which :func:`farthest_point_subset` computes every pair's distance at once.
PAIRWISE_ROWS = 1024
#: Rows up to which :func:`pairwise_distances` takes a matrix product, not ``cdist``.
GRAM_ROWS = 128
#: Distance below which :func:`farthest_point_subset` takes a row as equal to a chosen one.
SAME_DISTANCE = 1e-6


def pairwise_distances(a: np.ndarray, b: Optional[np.ndarray] = None) -> np.ndarray:
    """Euclidean distances (N, M) between the rows of ``a`` (N, d) and ``b`` (M, d; ``a``).

    Up to :data:`GRAM_ROWS` rows each, by ``|a|^2 + |b|^2 - 2 a.b`` (one matrix product;
    scipy's ``cdist`` costs more in a solve's first call when the caches are cold). Rounding
    leaves about 1.5e-8 times the rows' norm between equal rows (4e-8 for the cosines and sines
    of 6 joints, 3e-7 for 7 angles within 2 pi; below :data:`SAME_DISTANCE`). More rows:
    ``cdist`` (the product's temporaries cost more there).
    """
    a = np.asarray(a, dtype=np.float64)
    b = a if b is None else np.asarray(b, dtype=np.float64)
    if max(len(a), len(b)) > GRAM_ROWS:
        return cdist(a, b)
    d2 = a @ b.T
    d2 *= -2.0
    d2 += (a * a).sum(axis=1)[:, None]
    d2 += (b * b).sum(axis=1)[None, :]
    np.maximum(d2, 0.0, out=d2)
    return np.sqrt(d2, out=d2)


def farthest_point_subset(points: np.ndarray, k: int, first: int = 0, spacing: float = 0.0,
                          at_least: int = 1) -> np.ndarray:
    """Indices of ``k`` rows of ``points`` chosen greedily far apart (farthest-point sampling).

    With ``spacing`` > 0, fewer: once ``at_least`` rows are chosen, the choice stops when the
    farthest row left is within ``spacing`` of a chosen one (every row left is then as near
    one); a row equal to a chosen one is never chosen then.
    """
    n = len(points)
    if n == 0 or k < 1 or (n <= k and spacing <= 0):
        return np.arange(min(n, max(k, 0)))
    if n <= PAIRWISE_ROWS:
        # a few hundred rows (a solve's candidates, a seed table's neighbours): one compiled
        # call; more (a table's cells when built): a row of distances per pick
        return farthest_rows(as_arg(points), int(k),
                             int(first), float(spacing), int(at_least), SAME_DISTANCE)
    chosen = [first]
    dist = cdist(points[first:first + 1], points)[0]
    for _ in range(min(k, n) - 1):
        i = int(np.argmax(dist))
        if spacing > 0 and (dist[i] <= SAME_DISTANCE
                            or (dist[i] < spacing and len(chosen) >= at_least)):
            break
        chosen.append(i)
        np.minimum(dist, cdist(points[i:i + 1], points)[0], out=dist)
    return np.array(chosen)
