"""A voxel grid of distances to a table's cells: "is this goal near the data?" in one read."""

import math
from typing import Optional, Tuple

import numpy as np
from scipy.spatial import cKDTree

#: Edge of the reach grid's voxels [m], how far past the cells it reaches [m], and its most
#: voxels (a larger workspace gets none: every question goes to the KD-tree).
REACH_VOXEL = 0.05
REACH_PAD = 0.3
REACH_MAX_VOXELS = 2_000_000
#: Distances [m] past which a voxel keeps no distance (inf: "farther than this"), so that the
#: KD-tree's look-ups of the voxels far from every cell stop early.
REACH_CAP = 0.3


class ReachGrid:
    """How far each voxel's centre is from the nearest cell centre, on a grid over the cells.

    A point in a voxel is within the voxel's half diagonal of its centre, so the voxel's
    distance bounds the point's both ways: most questions "within d of the data?" are answered
    by one array read, and only points within a half diagonal of the answer's edge (or off the
    grid) need the KD-tree (docs/design.md, "Measured choices"). A voxel farther than
    :data:`REACH_CAP` from every cell keeps inf: its points are at least the cap less the half
    diagonal away.
    """

    def __init__(self, tree: cKDTree, centers: np.ndarray, dist: Optional[np.ndarray] = None):
        """The grid of ``centers`` (in ``tree``); ``dist``: its distances, computed before.

        Raises:
            ValueError: ``dist`` is not the grid's shape, or holds a negative or NaN value.
        """
        self.dist = None
        given = dist
        if len(centers) == 0 and given is None:
            return
        lo = centers.min(axis=0) - REACH_PAD if len(centers) else np.zeros(3)
        shape = np.ceil((centers.max(axis=0) + REACH_PAD - lo) / REACH_VOXEL).astype(int) \
            if len(centers) else np.zeros(3, dtype=int)
        if given is not None:  # the distances of a table loaded: its own grid's, checked
            given = np.asarray(given)
            if given.shape == (0,) and (len(centers) == 0
                                        or int(np.prod(shape)) > REACH_MAX_VOXELS):
                return
            if given.dtype != np.float64 or given.shape != tuple(shape) \
                    or not np.all(given >= 0):
                raise ValueError(f'reach grid distances of shape {given.shape} '
                                 f'({given.dtype}) for a grid of {tuple(shape)}')
        elif int(np.prod(shape)) > REACH_MAX_VOXELS:
            return
        if given is None:
            axes = [lo[i] + (np.arange(shape[i]) + 0.5) * REACH_VOXEL for i in range(3)]
            points = np.stack(np.meshgrid(*axes, indexing='ij'), axis=-1).reshape(-1, 3)
            given = tree.query(points, k=1, distance_upper_bound=REACH_CAP)[0].reshape(
                tuple(shape))
        self.dist = given
        self.lo = tuple(float(v) for v in lo)
        self.shape = tuple(int(v) for v in shape)
        # the half diagonal, and a margin for the rounding of the distances
        self.slack = REACH_VOXEL * math.sqrt(3) / 2 + 1e-9

    def bounds(self, position: np.ndarray) -> Optional[Tuple[float, float]]:
        """Least and most distance [m] from ``position`` to the nearest cell centre.

        None off the grid.
        """
        if self.dist is None:
            return None
        index = []
        for value, lo, size in zip(position, self.lo, self.shape):
            i = math.floor((float(value) - lo) / REACH_VOXEL)
            if not 0 <= i < size:
                return None
            index.append(i)
        d = float(self.dist[index[0], index[1], index[2]])
        if d == math.inf:  # farther than the cap from every cell centre
            return REACH_CAP - self.slack, math.inf
        return d - self.slack, d + self.slack

    def stored(self) -> np.ndarray:
        """The distances to store with a table ((0,) for none), for ``dist`` on loading."""
        return np.empty(0) if self.dist is None else self.dist
