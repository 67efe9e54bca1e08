"""The posture-index table: distinct posture indices per workspace cell, with a KD-tree.

After training, every dataset row is encoded to its posture index. Rows are grouped into cubic
cells of the tip position; per cell only indices that differ are kept (near-duplicates dropped,
then a far-apart subset when too many remain). A KD-tree over the cells' mean positions finds the
cells near a goal, and their indices are the candidates the decoder turns into joint solutions.

A table may also keep, per index, the tip orientation of the dataset row it came from (the paper's
KD-tree "over positions and orientations"): for a pose goal, the indices whose rows had an
orientation near the goal's keep a posture close to a solution.

A position-goal table may also keep, per index, its **decoded posture**: the decoder's output for
that index at the centre of its cell (8 bits per joint over the joint range), computed once when
the table is built. The solver refines from these instead of decoding the candidates at every
call: a goal is at most half a cell from the centre, which costs the refinement about one
iteration and saves the decoder's forward pass (see docs/benchmarks.md).
"""

import functools
import json
import math
from pathlib import Path
from typing import Dict, Optional, Protocol, Tuple
import zipfile

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist

from sik_ros.artifacts import (atomic_write, check_robot_manifest, FORMAT_VERSION, range_codes,
                               range_values)
from sik_ros.defaults import TableConfig  # noqa: F401 (part of this module's API)
from sik_ros.errors import ArtifactMismatch, CorruptArtifact, InvalidArgument
from sik_ros.kernels import as_arg
from sik_ros.kernels.sets import farthest_rows

TABLE_KEYS = ('centers', 'offsets', 'indices', 'manifest')


class PostureTable(Protocol):
    """What the solver needs of a table of posture indices.

    :class:`IndexTable` (built from a dataset) and :class:`PriorTable` (draws from a PSIK
    model's prior, for a model that comes without a table) implement it.

    Attributes:
        indices: (M, latent) float32 posture indices; a "row" is an index into it.
        orientations: (M, 4) unit quaternions x y z w of each row's tip, or None.
        postures: (M, n) each row decoded at its cell's centre [rad], or None.
    """

    indices: np.ndarray
    orientations: Optional[np.ndarray]
    postures: Optional[np.ndarray]

    @property
    def index_bounds(self) -> Tuple[np.ndarray, np.ndarray]:
        """Element-wise (min, max) of the indices."""

    def rows_near(self, position: np.ndarray, k_cells: int) -> np.ndarray:
        """Rows of the indices to try for a goal at ``position`` [m]."""

    def distance_to_data(self, position: np.ndarray) -> float:
        """How far ``position`` is from the data the table was made of [m]."""

    def within(self, position: np.ndarray, distance: float) -> bool:
        """Whether ``position`` lies within ``distance`` [m] of the data.

        As ``distance_to_data(position) <= distance``.
        """

    def oriented_rows(self, position: np.ndarray, quaternion: np.ndarray, count: int,
                      k_cells: int = 8) -> np.ndarray:
        """Rows near ``position`` whose tip orientations were nearest ``quaternion``."""


class PriorTable:
    """A :class:`PostureTable` for a PSIK model without a table: draws from its prior.

    PSIK's posture indices are trained towards N(0, I), so a fixed set of draws (the same for
    every target) stands in for the table's indices near the target. It knows nothing of the
    workspace: every goal counts as near the data.
    """

    orientations = None
    postures = None

    def __init__(self, latent_dim: int, count: int = 48, seed: int = 0):
        rng = np.random.default_rng(seed)
        self.indices = rng.standard_normal((count, latent_dim)).astype(np.float32)
        self.latent_dim = latent_dim

    @property
    def index_bounds(self) -> Tuple[np.ndarray, np.ndarray]:
        """Element-wise (min, max) of the draws."""
        return self.indices.min(axis=0), self.indices.max(axis=0)

    def rows_near(self, position: np.ndarray, k_cells: int) -> np.ndarray:
        """Every draw, whatever the position."""
        return np.arange(len(self.indices))

    def distance_to_data(self, position: np.ndarray) -> float:
        """0: the prior covers every goal."""
        return 0.0

    def within(self, position: np.ndarray, distance: float) -> bool:
        """True: the prior covers every goal."""
        return True

    def oriented_rows(self, position: np.ndarray, quaternion: np.ndarray, count: int,
                      k_cells: int = 8) -> np.ndarray:
        """Refused: prior draws carry no orientation.

        Raises:
            InvalidArgument: always.
        """
        raise InvalidArgument('a prior table keeps no orientations')


#: Edge of the reach grid's voxels [m], how far past the cells it reaches [m], and its most
#: voxels (a larger workspace gets none: every question goes to the KD-tree).
REACH_VOXEL = 0.05
REACH_PAD = 0.3
REACH_MAX_VOXELS = 2_000_000


class ReachGrid:
    """How far each voxel's centre is from the nearest cell centre, on a grid over the cells.

    A point in a voxel is within the voxel's half diagonal of its centre, so the voxel's
    distance bounds the point's both ways: most questions "within d of the data?" are answered
    by one array read, and only points within a half diagonal of the answer's edge (or off the
    grid) need the KD-tree. A solve asks once per call, where the KD look-up cost 10 us when
    warm and 40-120 us between a node's requests, when out of the caches.
    """

    def __init__(self, tree: cKDTree, centers: np.ndarray):
        self.dist = None
        if len(centers) == 0:
            return
        lo = centers.min(axis=0) - REACH_PAD
        shape = np.ceil((centers.max(axis=0) + REACH_PAD - lo) / REACH_VOXEL).astype(int)
        if int(np.prod(shape)) > REACH_MAX_VOXELS:
            return
        axes = [lo[i] + (np.arange(shape[i]) + 0.5) * REACH_VOXEL for i in range(3)]
        points = np.stack(np.meshgrid(*axes, indexing='ij'), axis=-1).reshape(-1, 3)
        self.dist = tree.query(points, k=1)[0].reshape(tuple(shape))
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
        return d - self.slack, d + self.slack


#: Rows up to which :func:`farthest_point_subset` computes every pair's distance at once.
PAIRWISE_ROWS = 1024
#: Rows up to which :func:`pairwise_distances` takes a matrix product, not ``cdist``.
GRAM_ROWS = 128
#: Distance below which :func:`farthest_point_subset` takes a row as equal to a chosen one.
SAME_DISTANCE = 1e-6


def pairwise_distances(a: np.ndarray, b: Optional[np.ndarray] = None) -> np.ndarray:
    """Euclidean distances (N, M) between the rows of ``a`` (N, d) and ``b`` (M, d; ``a``).

    Up to :data:`GRAM_ROWS` rows each, by ``|a|^2 + |b|^2 - 2 a.b`` (one matrix product):
    scipy's ``cdist``, as fast there, costs ~0.1 ms more in a solve's first call of it when
    the caches are cold. Rounding leaves about 1.5e-8 times the rows' norm between equal rows
    (4e-8 for the cosines and sines of 6 joints, 3e-7 for 7 angles within 2 pi; below
    :data:`SAME_DISTANCE`). More rows: ``cdist`` (the product's temporaries cost more there).
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


class IndexTable:
    """Cells of tip positions, each with its distinct posture indices.

    ``orientations`` (optional, (M, 4) unit quaternions x, y, z, w): the tip orientation of the
    dataset row each index was kept from. ``postures`` (optional, (M, n) [rad]): each index
    decoded at its cell's centre (see :func:`decode_postures`); the manifest's ``postures``
    entry holds the joint range they are quantised over.
    """

    def __init__(self, centers: np.ndarray, offsets: np.ndarray, indices: np.ndarray,
                 manifest: Dict, orientations: Optional[np.ndarray] = None,
                 postures: Optional[np.ndarray] = None):
        self.centers = np.asarray(centers, dtype=np.float64)
        self.offsets = np.asarray(offsets, dtype=np.int64)
        self.indices = np.asarray(indices, dtype=np.float32)
        self.orientations = None
        if orientations is not None:
            quat = np.asarray(orientations, dtype=np.float32)
            self.orientations = quat / np.linalg.norm(quat, axis=1, keepdims=True)
        self.postures = None if postures is None else np.asarray(postures, dtype=np.float32)
        self.manifest = manifest
        self.tree = cKDTree(self.centers)
        self.reach = ReachGrid(self.tree, self.centers)
        self.cell = float(manifest['table_config']['cell'])
        self.latent_dim = self.indices.shape[1]

    def __len__(self) -> int:
        """Number of cells."""
        return len(self.centers)

    def candidates(self, position: np.ndarray, k_cells: int = 8) -> np.ndarray:
        """Posture indices of the ``k_cells`` cells nearest a position [m], (M, latent)."""
        return self.indices[self.rows_near(position, k_cells)]

    def oriented_candidates(self, position: np.ndarray, quaternion: np.ndarray, count: int,
                            k_cells: int = 8) -> np.ndarray:
        """Indices near a position whose rows' orientations were nearest a quaternion.

        Returns the ``count`` indices of the cells near ``position`` whose dataset rows had tip
        orientations nearest ``quaternion`` (x, y, z, w), nearest first, (M, latent).

        Raises:
            InvalidArgument: the table keeps no orientations.
        """
        return self.indices[self.oriented_rows(position, quaternion, count, k_cells)]

    def oriented_rows(self, position: np.ndarray, quaternion: np.ndarray, count: int,
                      k_cells: int = 8) -> np.ndarray:
        """Table rows of :meth:`oriented_candidates` (indices into ``indices``)."""
        if self.orientations is None:
            raise InvalidArgument('this index table keeps no orientations (rebuild it with '
                                  'sik-index --orientations)')
        rows = self.rows_near(position, k_cells)
        closeness = np.abs(self.orientations[rows] @ np.asarray(quaternion, dtype=np.float32))
        if count < len(rows):
            # the ``count`` nearest, then in order (ties by row, as a stable sort of all)
            best = np.argpartition(-closeness, count - 1)[:count]
            best = best[np.lexsort((best, -closeness[best]))]
        else:
            best = np.argsort(-closeness, kind='stable')
        return rows[best]

    def cell_centers(self, rows: np.ndarray) -> np.ndarray:
        """Centre [m] of the cell of each table row, (M, 3)."""
        return self.centers[np.searchsorted(self.offsets, rows, side='right') - 1]

    def with_postures(self, postures: np.ndarray, lower: np.ndarray,
                      upper: np.ndarray) -> 'IndexTable':
        """This table with decoded postures (M, n) [rad] quantised over ``lower``..``upper``."""
        postures = np.asarray(postures, dtype=np.float32)
        if postures.shape[0] != len(self.indices) or not np.all(np.isfinite(postures)):
            raise InvalidArgument(f'postures must be finite with {len(self.indices)} rows; got '
                                  f'shape {postures.shape}')
        manifest = dict(self.manifest, postures={'lower': [float(v) for v in lower],
                                                 'upper': [float(v) for v in upper]})
        return IndexTable(self.centers, self.offsets, self.indices, manifest, self.orientations,
                          postures)

    def rows_near(self, position: np.ndarray, k_cells: int) -> np.ndarray:
        """Table rows (indices into ``indices``) of the ``k_cells`` cells nearest a position."""
        k = min(k_cells, len(self.centers))
        _, cells = self.tree.query(np.asarray(position, dtype=float), k=k)
        cells = np.atleast_1d(cells)
        # the cells' row ranges end to end, without a Python step per cell (27 cells: 0.3x
        # the time of concatenating an arange per cell)
        first, size = self.offsets[cells], self.offsets[cells + 1] - self.offsets[cells]
        return np.repeat(first - np.cumsum(size) + size, size) + np.arange(size.sum())

    def distance_to_data(self, position: np.ndarray) -> float:
        """Distance from a position to the nearest cell centre [m]."""
        d, _ = self.tree.query(np.asarray(position, dtype=float), k=1)
        return float(d)

    def within(self, position: np.ndarray, distance: float) -> bool:
        """Whether ``position`` lies within ``distance`` [m] of the nearest cell centre.

        From the :class:`ReachGrid` where it can tell, else from the KD-tree.
        """
        bounds = self.reach.bounds(position)
        if bounds is not None:
            if bounds[1] <= distance:
                return True
            if bounds[0] > distance:
                return False
        return self.distance_to_data(position) <= distance

    @functools.cached_property
    def index_bounds(self):
        """Element-wise (min, max) of the stored indices, computed once (0.3 ms a pose table)."""
        return self.indices.min(axis=0), self.indices.max(axis=0)

    # -- building and files -----------------------------------------------------------------

    @classmethod
    def build(cls, z: np.ndarray, position: np.ndarray, cfg: TableConfig,
              manifest: Dict, quaternion: Optional[np.ndarray] = None) -> 'IndexTable':
        """Group encoded rows into cells and keep distinct, far-apart indices per cell.

        With ``quaternion`` (the rows' tip orientations), each kept index keeps its row's.
        """
        position = np.asarray(position)
        cell_idx = np.floor(position / cfg.cell).astype(np.int64) + (1 << 20)
        keys = (cell_idx[:, 0] << 42) | (cell_idx[:, 1] << 21) | cell_idx[:, 2]
        quant = np.round(z / cfg.dedup).astype(np.int64)
        # sort by cell, then by quantised index, to drop duplicates per cell in one pass
        order = np.lexsort(tuple(quant[:, j] for j in reversed(range(quant.shape[1]))) + (keys,))
        keys_s, quant_s = keys[order], quant[order]
        new = np.ones(len(order), dtype=bool)
        new[1:] = (keys_s[1:] != keys_s[:-1]) | np.any(quant_s[1:] != quant_s[:-1], axis=1)
        rows = order[new]
        keys_u = keys_s[new]
        starts = np.flatnonzero(np.r_[True, keys_u[1:] != keys_u[:-1]])
        ends = np.r_[starts[1:], len(rows)]
        sums = np.zeros((len(starts), 3))
        counts = np.zeros(len(starts))
        cell_of_row = np.searchsorted(np.unique(keys), keys)
        np.add.at(sums, cell_of_row, position)
        np.add.at(counts, cell_of_row, 1)
        centers = sums / counts[:, None]
        kept, offsets = [], [0]
        for s, e in zip(starts, ends):
            cell_rows = rows[s:e]
            if len(cell_rows) > cfg.max_per_cell:
                cell_rows = cell_rows[farthest_point_subset(z[cell_rows], cfg.max_per_cell)]
            kept.append(cell_rows)
            offsets.append(offsets[-1] + len(cell_rows))
        kept_rows = np.concatenate(kept)
        # at the precision they are stored with, so a built table is the table loaded later
        indices = z[kept_rows].astype(np.float16).astype(np.float32)
        orientations = None
        if quaternion is not None:
            order_rows = np.argsort(kept_rows)  # sorted reads from a memory-mapped array
            orientations = np.empty((len(kept_rows), 4), dtype=np.float32)
            orientations[order_rows] = np.asarray(quaternion[kept_rows[order_rows]])
        manifest = dict(manifest, table_config={'cell': cfg.cell, 'dedup': cfg.dedup,
                                                'max_per_cell': cfg.max_per_cell},
                        cells=int(len(centers)), entries=int(len(indices)),
                        orientations=orientations is not None,
                        kind='sik_index_table', format_version=FORMAT_VERSION)
        return cls(centers, np.array(offsets), indices, manifest, orientations)

    def save(self, path: Path) -> Path:
        """Write the table atomically as a compressed ``.npz`` (indices stored as float16)."""
        path = Path(path)
        extra = {}
        if self.orientations is not None:  # 8-bit quaternions: ~1 degree, enough to choose
            extra['orientations'] = np.round(self.orientations * 127).astype(np.int8)
        if self.postures is not None:  # 8 bits over each joint's range: < 0.015 rad
            lower, upper = (np.array(self.manifest['postures'][k]) for k in ('lower', 'upper'))
            extra['postures'] = range_codes(self.postures, lower, upper, np.uint8)
        with atomic_write(path) as tmp:
            np.savez_compressed(tmp, centers=self.centers.astype(np.float32),
                                offsets=self.offsets, indices=self.indices.astype(np.float16),
                                manifest=np.array(json.dumps(self.manifest, sort_keys=True)),
                                **extra)
        return path

    @classmethod
    def load(cls, path: Path, robot_manifest: Optional[Dict] = None,
             signature: Optional[Dict] = None) -> 'IndexTable':
        """Read a table, checking it against a robot and the model it was built with.

        Raises:
            CorruptArtifact: unreadable or inconsistent file.
            ArtifactMismatch: a table of another robot or another model.
        """
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as f:
                if any(k not in f for k in TABLE_KEYS):
                    raise CorruptArtifact(f'index table {path} lacks arrays {TABLE_KEYS}')
                centers, offsets = f['centers'], f['offsets']
                indices = f['indices'].astype(np.float32)
                manifest = json.loads(str(f['manifest']))
                orientations = f['orientations'].astype(np.float32) \
                    if 'orientations' in f else None
                codes = f['postures'] if 'postures' in f else None
        except CorruptArtifact:
            raise
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
            raise CorruptArtifact(f'cannot read index table {path}: {exc}') from exc
        if manifest.get('kind') != 'sik_index_table':
            raise CorruptArtifact(f'{path} is not a sik_ros index table')
        if (len(offsets) != len(centers) + 1 or offsets[-1] != len(indices)
                or len(centers) != manifest.get('cells')):
            raise CorruptArtifact(f'index table {path}: sizes disagree with its manifest')
        if bool(manifest.get('orientations', False)) != (orientations is not None) or (
                orientations is not None and (orientations.shape != (len(indices), 4)
                                              or not np.all(np.any(orientations != 0, axis=1)))):
            raise CorruptArtifact(f'index table {path}: orientations disagree with its manifest')
        postures = cls._postures_from_codes(path, manifest, codes, len(indices))
        if robot_manifest is not None:
            check_robot_manifest(f'index table {path}', robot_manifest, manifest['robot'])
        if signature is not None and manifest.get('model') != signature:
            raise ArtifactMismatch(f'index table {path}: model', signature,
                                   manifest.get('model'))
        return cls(centers, offsets, indices, manifest, orientations, postures)

    @staticmethod
    def _postures_from_codes(path, manifest: Dict, codes: Optional[np.ndarray],
                             entries: int) -> Optional[np.ndarray]:
        """Decoded postures [rad] from their 8-bit codes, checked against the manifest."""
        spec = manifest.get('postures')
        if spec is None and codes is None:
            return None
        try:
            lower = np.asarray(spec['lower'], dtype=float)
            upper = np.asarray(spec['upper'], dtype=float)
            ok = (codes is not None and codes.dtype == np.uint8 and lower.shape == upper.shape
                  and codes.shape == (entries, len(lower)) and np.all(np.isfinite(lower))
                  and np.all(np.isfinite(upper)) and np.all(upper > lower))
        except (TypeError, KeyError, ValueError):
            ok = False
        if not ok:
            raise CorruptArtifact(f'index table {path}: postures disagree with its manifest')
        return range_values(codes, lower, upper).astype(np.float32)
