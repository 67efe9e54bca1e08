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
iteration and saves the decoder's forward pass (see docs/benchmarks.md). Such a table may mark
the indices the decoder **realises** (``sik-index --max-tip-error``, the manifest's ``realised``
entry): those whose decoded tip lands near the goal around their cell. Its look-up by position
then gives only those, from as many more cells as hold as many of them
(:meth:`IndexTable.pool_cells`); the look-up by orientation still chooses among every row.
"""

import functools
import json
import math
from pathlib import Path
from typing import Dict, Optional, Protocol, Tuple
import zipfile

import numpy as np
from scipy.spatial import cKDTree

from sik_ros.artifacts import (atomic_write, check_robot_manifest, FORMAT_VERSION, range_codes,
                               range_values)
from sik_ros.defaults import TableConfig
from sik_ros.errors import ArtifactMismatch, CorruptArtifact, InvalidArgument
from sik_ros.kernels import as_arg
from sik_ros.kernels.cells import (best_oriented, cell_rows, CellGrid, MAX_SHELLS,
                                   nearest_cells)
from sik_ros.tables.point_sets import farthest_point_subset
from sik_ros.tables.reach_grid import ReachGrid

TABLE_KEYS = ('centers', 'offsets', 'indices', 'manifest')


class PostureTable(Protocol):
    """What the solver needs of a table of posture indices.

    :class:`IndexTable` (built from a dataset) and
    :class:`~sik_ros.tables.prior_table.PriorTable` (draws from a PSIK model's prior, for a model
    that comes without a table) implement it.

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

    def pool_cells(self, k_cells: int) -> int:
        """Cells holding about as many rows as ``k_cells`` cells of an unfiltered table."""

    def distance_to_data(self, position: np.ndarray) -> float:
        """How far ``position`` is from the data the table was made of [m]."""

    def within(self, position: np.ndarray, distance: float) -> bool:
        """Whether ``position`` lies within ``distance`` [m] of the data.

        As ``distance_to_data(position) <= distance``.
        """

    def oriented_rows(self, position: np.ndarray, quaternion: np.ndarray, count: int,
                      k_cells: int = 8) -> np.ndarray:
        """Rows near ``position`` whose tip orientations were nearest ``quaternion``."""


class IndexTable:
    """Cells of tip positions, each with its distinct posture indices.

    ``orientations`` (optional, (M, 4) unit quaternions x, y, z, w): the tip orientation of the
    dataset row each index was kept from. ``postures`` (optional, (M, n) [rad]): each index
    decoded at its cell's centre (see :func:`decode_postures`); the manifest's ``postures``
    entry holds the joint range they are quantised over. ``realised`` (optional, (M,) bool):
    the rows the look-up by position gives (see :func:`~sik_ros.learning.indexing.mark_realised`).
    """

    def __init__(self, centers: np.ndarray, offsets: np.ndarray, indices: np.ndarray,
                 manifest: Dict, orientations: Optional[np.ndarray] = None,
                 postures: Optional[np.ndarray] = None, realised: Optional[np.ndarray] = None,
                 reach: Optional[np.ndarray] = None, like: Optional['IndexTable'] = None):
        """A table of its arrays (see the class).

        ``reach``: the :class:`ReachGrid`'s distances stored with the table
        (:meth:`ReachGrid.stored`), which the grid then takes instead of computing them;
        ``like``: a table of the same cells, whose KD-tree and grids this one shares.

        Raises:
            ValueError: ``reach`` is not the grid of these cells.
        """
        self.centers = np.asarray(centers, dtype=np.float64)
        self.offsets = np.asarray(offsets, dtype=np.int64)
        self.indices = np.asarray(indices, dtype=np.float32)
        self.orientations = None
        if orientations is not None:
            quat = np.asarray(orientations, dtype=np.float32)
            self.orientations = quat / np.linalg.norm(quat, axis=1, keepdims=True)
        self.postures = None if postures is None else np.asarray(postures, dtype=np.float32)
        self.realised = None if realised is None else np.asarray(realised, dtype=bool)
        # the share of rows realised, counted once (the rows do not change; a look-up needs it)
        self._realised_share = None if realised is None else \
            np.count_nonzero(self.realised) / max(len(self.indices), 1)
        self.manifest = manifest
        self.cell = float(manifest['table_config']['cell'])
        if like is not None and like.centers is self.centers and like.cell == self.cell:
            self.tree, self.reach, self.grid = like.tree, like.reach, like.grid
        else:
            self.tree = cKDTree(self.centers)
            self.reach = ReachGrid(self.tree, self.centers, reach)
            self.grid = CellGrid.build(self.centers, self.cell)
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
        rows = self.rows_in_cells(position, k_cells)
        return best_oriented(rows, self.orientations,
                             np.asarray(quaternion, dtype=np.float32).ravel(), count)

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
                          postures, self.realised, like=self)

    def pool_cells(self, k_cells: int) -> int:
        """Cells whose realised rows are about as many as the rows of ``k_cells`` cells.

        ``k_cells`` for a table that marks no realised rows; more for one that does, by the
        share of rows it marks.
        """
        if self._realised_share is None:
            return k_cells
        share = self._realised_share
        return max(k_cells, math.ceil(k_cells / max(share, 1e-9)))

    def rows_near(self, position: np.ndarray, k_cells: int) -> np.ndarray:
        """Table rows of the ``k_cells`` cells nearest a position: the realised ones if marked."""
        rows = self.rows_in_cells(position, k_cells)
        return rows if self.realised is None else rows[self.realised[rows]]

    def rows_in_cells(self, position: np.ndarray, k_cells: int) -> np.ndarray:
        """Every table row (index into ``indices``) of the ``k_cells`` cells nearest a position."""
        k = min(k_cells, len(self.centers))
        point = as_arg(position).ravel()
        cells = np.empty(0, dtype=np.int64)
        if self.grid is not None and np.isfinite(point).all():
            # the grid's boxes around the point: the KD-tree's cells without its Python call
            # (most of a table look-up's time; docs/design.md, "Measured choices")
            g = self.grid
            cells = nearest_cells(point, self.centers, self.cell, g.origin, g.dims, g.starts,
                                  g.order, k, MAX_SHELLS)
        if len(cells) == 0:
            _, cells = self.tree.query(point, k=k)
            cells = np.atleast_1d(cells).astype(np.int64)
        return cell_rows(cells, self.offsets)

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
        """Element-wise (min, max) of the stored indices, computed once."""
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
        if self.realised is not None:
            extra['realised'] = np.packbits(self.realised)
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
                bits = f['realised'] if 'realised' in f else None
        except CorruptArtifact:
            raise
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
            raise CorruptArtifact(f'cannot read index table {path}: {exc}') from exc
        if manifest.get('kind') != 'sik_index_table':
            raise CorruptArtifact(f'{path} is not a sik_ros index table')
        if (len(offsets) != len(centers) + 1 or offsets[-1] != len(indices)
                or len(centers) != manifest.get('cells') or np.any(np.diff(offsets) < 1)):
            raise CorruptArtifact(f'index table {path}: sizes disagree with its manifest')
        realised = cls._realised_from_bits(path, manifest.get('realised'), bits, offsets)
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
        return cls(centers, offsets, indices, manifest, orientations, postures, realised)

    @staticmethod
    def _realised_from_bits(path, spec: Optional[Dict], bits: Optional[np.ndarray],
                            offsets: np.ndarray) -> Optional[np.ndarray]:
        """The realised rows from their bits, checked against the manifest's entry.

        Every cell must keep one at least.
        """
        if spec is None and bits is None:
            return None
        try:
            mask = np.unpackbits(bits, count=int(offsets[-1])).astype(bool)
            ok = (math.isfinite(spec['max_tip_error']) and spec['max_tip_error'] > 0
                  and math.isfinite(spec['probe']) and spec['probe'] >= 0
                  and int(spec['entries']) == np.count_nonzero(mask)
                  and np.all(np.add.reduceat(mask, offsets[:-1]) >= 1))
        except (TypeError, KeyError, ValueError):
            ok = False
        if not ok:
            raise CorruptArtifact(f'index table {path}: its realised rows disagree with its '
                                  f'manifest ({spec})')
        return mask

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
