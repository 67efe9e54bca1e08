"""Dataset configurations looked up by their tip pose: where pose solutions start.

They are the starts of isolated pose solutions and of the family search.

An arm of six joints or fewer reaches a pose at isolated configurations (up to 8 branches for a
6-joint arm, times the 2 pi equivalents of periodic joints): there is no self-motion to walk from
one to the next, so every branch needs a start of its own. The collected dataset already holds,
for every branch, configurations whose tips are near any pose (the paper's KD-tree and
dictionary, keyed by the whole pose instead of the position). A :class:`SeedTable` keeps a
random subset of the dataset's configurations; when loaded it computes their tip poses by
forward kinematics and puts them in a KD-tree over ``(position [m], scale * quaternion)``. For
a goal, :meth:`SeedTable.starts` takes the configurations whose tips are nearest the goal pose
and thins them to a subset far apart in joint space (one per branch, as far as they go), which
refinement then takes onto the goal in a few steps (more branches in less time than random
starts; docs/design.md).

A 7-joint arm's table is smaller (:data:`~sik_ros.defaults.SEARCH_SEED_TABLE_ROWS`): its starts
serve the family search (:mod:`sik_ros.solver.families.search`), which traces every curve of the
self-motion through the solutions they reach. The nearest rows of a small table lie farther
from the goal and farther apart, on more of the pose's curves; a self-motion loop or a sliver
of a curve by the limits that no model posture leads to is reached from one of them.

An arm's first joint turns the whole arm about its own axis, a line fixed to the base
(:func:`first_axis`): a pose turned about that line is reached by turning the first joint
alike. Every row is keyed by its tip pose in a frame along that axis (:func:`to_axis_frame`)
turned to azimuth 0 (onto the half-plane y = 0, :func:`turned`), its first joint turned back
with it, and a goal is looked up turned alike; the rows found get the goal's azimuth on their
first joint. Every row then serves every azimuth: the same table is one dimension denser, and
the starts lie about half as far from the goal. A first joint short of a whole turn (the
SO-100's spans 4 rad) cannot take every goal's azimuth: the look-up goes further until it has
``neighbours`` rows that can.
"""

import json
import math
from pathlib import Path
from typing import Dict, Optional, Tuple
import zipfile

import numpy as np

from sik_ros.artifacts import (atomic_write, check_robot_manifest, FORMAT_VERSION, range_codes,
                               range_values)
from sik_ros.defaults import SEARCH_SEED_TABLE_ROWS, SEED_TABLE_ROWS
from sik_ros.errors import ArtifactMismatch, CorruptArtifact, InvalidArgument
from sik_ros.kernels.angles import TURN
from sik_ros.kernels.kdtree import KDTree
from sik_ros.kernels.seeds import axis_key, table_starts
from sik_ros.kinematics.branches import branch_signs
from sik_ros.kinematics.robot import Robot
from sik_ros.kinematics.rotations import rotation_to_quaternion
from sik_ros.tables.axis_frame import first_axis, to_axis_frame, turned
from sik_ros.tables.dataset import Dataset
from sik_ros.tables.point_sets import SAME_DISTANCE

#: Configurations a seed table keeps by default (6 MB for 6 joints).
DEFAULT_ROWS = SEED_TABLE_ROWS
#: Metres that one unit of quaternion distance counts as in the look-up (about 0.15 m per
#: radian of tip rotation) [m].
QUATERNION_SCALE = 0.3
#: Nearest configurations by tip pose that the far-apart starts are chosen among.
NEIGHBOURS = 100
#: Relative slack of the KD-tree look-up (each row found within 1.5 times the distance of the
#: true k-th nearest): nearly the exact look-up's rows in half its time.
LOOKUP_EPS = 0.5
#: A look-up whose nearest rows cannot take the goal's azimuth (a first joint short of a whole
#: turn) goes at most to this many times ``neighbours`` rows (the rows of a branch the goal has
#: not, within the limits, can lie that far: some seconds to look up the whole table).
LOOKUP_MOST = 8
#: Starts no nearer each other than this (distance of their joints' cosines and sines, about
#: radians when near), at least ``START_LEAST`` of them: nearer ones reach the same solution.
START_SPACING = 1.2
START_LEAST = 8
#: Rows per leaf of the KD-tree.
LEAF_SIZE = 32


class SeedTable:
    """Configurations (M, n) [rad] in a KD-tree keyed by their tip poses.

    Attributes:
        q: the configurations (M, n) [rad], within the robot's limits.
        manifest: what the table was built from (robot, rows, dataset).
        signs: the arm's branch signs (:mod:`sik_ros.kinematics.branches`; None above six
            joints), and ``codes`` (M,): each row's branch code, whose rows
            :meth:`branch_starts` looks up apart.
    """

    def __init__(self, robot: Robot, q: np.ndarray, manifest: Dict):
        self.q = np.asarray(q, dtype=np.float64)
        self.manifest = manifest
        self._lower, self._upper = robot.lower[0], robot.upper[0]
        p, quat = robot.fk_batch(self.q)
        # the first joint turns the whole arm about its own axis, fixed to the base: a pose
        # turned about that axis is reached by turning the first joint alike. Rows are keyed
        # by their tip poses in a frame along that axis, turned to azimuth 0 (the half-plane
        # y = 0), their first joint turned back with them: every row serves every azimuth
        self._axis = first_axis(robot)
        self._base_q = self.q
        if self._axis is not None:
            self._axis = tuple(np.ascontiguousarray(a, dtype=np.float64) for a in self._axis)
            # the frame's inverse as a quaternion, once (a look-up would convert it every call)
            self._inverse = np.ascontiguousarray(
                rotation_to_quaternion(self._axis[1].T[None])[0])
            p, quat = to_axis_frame(self._axis, p, quat, self._inverse)
            azimuth = np.arctan2(p[:, 1], p[:, 0])
            p, quat = turned(p, quat, -azimuth)
            self._base_q = self.q.copy()
            self._base_q[:, 0] -= azimuth
        keys = np.concatenate([p, QUATERNION_SCALE * quat], axis=1)
        self.tree = KDTree(keys, LEAF_SIZE)
        order = self.tree.order
        if np.any(order != np.arange(len(order))):
            # the rows in the tree's leaf order (a table saved after this loads in it): a leaf's
            # rows lie together in memory, for look-ups after other work has emptied the caches
            same = self._base_q is self.q  # no first axis: one array, kept one
            self.q = self.q[order]
            self._base_q = self.q if same else self._base_q[order]
            keys = keys[order]
        self._base_q = np.ascontiguousarray(self._base_q)
        # the rows of each branch code apart, in a tree of their own: starts on a branch that
        # the nearest rows of the whole table leave out (kinematics.branches)
        self.signs = branch_signs(robot) if robot.dof <= 6 else None
        self.codes = None if self.signs is None else self.signs.codes(robot, self.q)
        self._by_code = {}
        if self.codes is not None:
            for code in np.unique(self.codes):
                rows = np.flatnonzero(self.codes == code)
                tree = KDTree(keys[rows], LEAF_SIZE)
                self._by_code[int(code)] = (tree, np.ascontiguousarray(
                    self._base_q[rows][tree.order]))

    def __len__(self) -> int:
        """Number of configurations."""
        return len(self.q)

    def starts(self, position: np.ndarray, quaternion: np.ndarray, count: int,
               neighbours: int = NEIGHBOURS) -> np.ndarray:
        """Up to ``count`` configurations (rows, n) [rad] whose tips were near a pose, far apart.

        Args:
            position: goal position (3,) [m] in the base frame.
            quaternion: goal orientation, a unit quaternion x y z w (either sign).
            count: most configurations wanted (fewer when the rest would be within
                :data:`START_SPACING` of those taken, the table is smaller, or its rows'
                first joints cannot take the goal's azimuth).
            neighbours: nearest configurations (by tip pose) the far-apart ones come from.
        """
        return self._starts(self.tree, self._base_q, position, quaternion, count, neighbours)

    def branch_starts(self, position: np.ndarray, quaternion: np.ndarray, code: int,
                      count: int, neighbours: int = NEIGHBOURS) -> np.ndarray:
        """As :meth:`starts`, from the rows of one branch code only (:attr:`codes`).

        Rows (0, n) when the table holds none of that code (or has no branch signs).
        """
        if int(code) not in self._by_code:
            return np.empty((0, self.q.shape[1]))
        tree, base_q = self._by_code[int(code)]
        return self._starts(tree, base_q, position, quaternion, count, neighbours)

    def _starts(self, tree: KDTree, base_q: np.ndarray, position: np.ndarray,
                quaternion: np.ndarray, count: int, neighbours: int) -> np.ndarray:
        """:meth:`starts` from ``tree`` over the rows ``base_q`` (in its leaf order)."""
        k = min(neighbours, len(base_q))
        if count < 1 or k < 1:
            return np.empty((0, self.q.shape[1]))
        key, azimuth = self.turned_key(position, quaternion)
        # rows whose first joint cannot take the goal's azimuth within its limits are left
        # out: look further until ``k`` of them can (a first joint short of a whole turn). The
        # first look-up asks for as many more as the joint's share of a turn leaves out, and a
        # quarter more (SO-100, a 4 rad first joint: one look-up in most calls, where starting
        # from ``k`` took two or more in half of them)
        wanted = k
        share = (self._upper - self._lower) / TURN
        if self._axis is not None and share < 1.0:
            wanted = min(len(base_q), math.ceil(1.25 * k / max(share, 1e-3)))
        # a quaternion and its negative are one rotation (the table's have w >= 0): the other
        # sign's key is looked up too, where it can be nearer than the k-th row found (keys
        # with w near 0: every row is at least ``scale * w`` from it)
        other = np.concatenate([key[:3], -key[3:]])
        # far apart in joint space, an angle and its 2 pi equivalents alike; no two within
        # START_SPACING, which head for one solution (at least START_LEAST of them)
        reals = np.array([azimuth, self._lower, self._upper, LOOKUP_EPS, START_SPACING,
                          SAME_DISTANCE], dtype=float)
        ints = np.array([self._axis is not None, k, wanted,
                         max(int(wanted), LOOKUP_MOST * int(k)), count, START_LEAST],
                        dtype=np.int64)
        return table_starts(*tree.arrays(), base_q, key, other, reals, ints)

    def turned_key(self, position: np.ndarray, quaternion: np.ndarray
                   ) -> Tuple[np.ndarray, float]:
        """A goal's key (7,) and its azimuth [rad] (0 without a first axis).

        The key: the goal's position [m] and :data:`QUATERNION_SCALE` times its quaternion
        (w >= 0), in the first axis's frame turned to azimuth 0 (:func:`to_axis_frame`, then
        :func:`turned`) when the arm has one.
        """
        position = np.asarray(position, dtype=np.float64)
        quaternion = np.asarray(quaternion, dtype=np.float64)
        if self._axis is None:
            quat = -quaternion if quaternion[3] < 0 else quaternion  # as the table's
            return np.concatenate([position, QUATERNION_SCALE * quat]), 0.0
        return axis_key(self._axis[0], self._axis[1], self._inverse, position, quaternion,
                        QUATERNION_SCALE)

    # -- the built state, for a cache ------------------------------------------------------

    def state(self) -> Dict[str, np.ndarray]:
        """What :meth:`from_state` needs to skip the FK, trees and branch codes of a build.

        The rows' 16-bit joint codes (as :meth:`save` writes them; the rows are their values)
        in the tree's leaf order, the first joint turned back to azimuth 0, the trees, and each
        branch code's rows (``by_code_*``).
        """
        rm = self.manifest['robot']
        out = {'codes': range_codes(self.q, np.asarray(rm['lower']), np.asarray(rm['upper']),
                                    np.uint16),
               'base_q0': np.ascontiguousarray(self._base_q[:, 0])}
        out.update({f'tree_{k}': v for k, v in self.tree.state().items()})
        if self.codes is not None:
            out['branch_codes'] = np.asarray(self.codes, dtype=np.int64)
            keys = sorted(self._by_code)
            out['by_code_keys'] = np.array(keys, dtype=np.int64)
            for i, code in enumerate(keys):
                out.update({f'by_code_{i}_{k}': v
                            for k, v in self._by_code[code][0].state().items()})
        return out

    @classmethod
    def from_state(cls, robot: Robot, state: Dict[str, np.ndarray],
                   manifest: Dict) -> 'SeedTable':
        """The table :meth:`state` described, for ``robot``, its arrays checked.

        Raises:
            CorruptArtifact: an array missing, of another type or shape, or a tree that is
                not one (:meth:`~sik_ros.kernels.kdtree.KDTree.from_state`).
        """
        try:
            return cls._from_state(robot, state, manifest)
        except (KeyError, ValueError, TypeError) as exc:
            raise CorruptArtifact(f'seed table state: {exc}') from exc

    @classmethod
    def _from_state(cls, robot: Robot, state: Dict[str, np.ndarray],
                    manifest: Dict) -> 'SeedTable':
        codes, base_q0 = state['codes'], state['base_q0']
        rows = manifest.get('rows')
        if codes.dtype != np.uint16 or codes.shape != (rows, robot.dof) or len(codes) == 0 \
                or base_q0.dtype != np.float64 or base_q0.shape != (rows,) \
                or not np.all(np.isfinite(base_q0)):
            raise ValueError(f'codes {codes.shape} and base_q0 {base_q0.shape} for {rows} '
                             f'rows of {robot.dof} joints')
        table = cls.__new__(cls)
        table.manifest = manifest
        table.q = range_values(codes, robot.lower, robot.upper)
        table._lower, table._upper = robot.lower[0], robot.upper[0]
        table._axis = first_axis(robot)
        table._base_q = table.q
        if table._axis is not None:
            table._axis = tuple(np.ascontiguousarray(a, dtype=np.float64) for a in table._axis)
            table._inverse = np.ascontiguousarray(
                rotation_to_quaternion(table._axis[1].T[None])[0])
            table._base_q = table.q.copy()
            table._base_q[:, 0] = base_q0
        table._base_q = np.ascontiguousarray(table._base_q)
        table.tree = KDTree.from_state({k: state[f'tree_{k}'] for k in KDTree.STATE})
        if len(table.tree) != rows:
            raise ValueError(f'a tree of {len(table.tree)} points for {rows} rows')
        table.signs = branch_signs(robot) if robot.dof <= 6 else None
        table.codes, table._by_code = None, {}
        if table.signs is None:
            return table
        table.codes = state['branch_codes']
        keys = state['by_code_keys']
        if table.codes.dtype != np.int64 or table.codes.shape != (rows,) \
                or keys.dtype != np.int64 or keys.ndim != 1 \
                or not np.array_equal(keys, np.unique(table.codes)):
            raise ValueError('branch codes disagree with their rows')
        for i, code in enumerate(keys):
            tree = KDTree.from_state({k: state[f'by_code_{i}_{k}'] for k in KDTree.STATE})
            members = np.flatnonzero(table.codes == code)
            if len(tree) != len(members):
                raise ValueError(f'branch code {code}: a tree of {len(tree)} points for '
                                 f'{len(members)} rows')
            table._by_code[int(code)] = (tree, np.ascontiguousarray(
                table._base_q[members][tree.order]))
        return table

    # -- building and files -----------------------------------------------------------------

    @classmethod
    def build(cls, robot: Robot, dataset: Dataset, rows: int = DEFAULT_ROWS,
              seed: int = 0) -> 'SeedTable':
        """A table of ``rows`` configurations drawn from a dataset (all when it is smaller).

        Raises:
            InvalidArgument: ``rows`` below 1, or an empty dataset.
        """
        if isinstance(rows, bool) or not isinstance(rows, (int, np.integer)) or rows < 1:
            raise InvalidArgument(f'seed table rows must be an integer >= 1; got {rows!r}')
        total = len(dataset)
        if total < 1:
            raise InvalidArgument('a seed table needs a dataset with rows')
        pick = np.arange(total) if rows >= total else np.sort(
            np.random.default_rng(seed).choice(total, size=rows, replace=False))
        q = np.clip(np.asarray(dataset.q[pick]), robot.lower, robot.upper)
        manifest = {'kind': 'sik_seed_table', 'format_version': FORMAT_VERSION,
                    'robot': robot.manifest(), 'rows': int(len(q)), 'seed': int(seed),
                    'dataset': {'count': total, 'params': dataset.manifest.get('params')}}
        # as stored: a built table is the table loaded later
        return cls(robot, range_values(range_codes(q, robot.lower, robot.upper, np.uint16),
                                       robot.lower, robot.upper), manifest)

    def save(self, path: Path) -> Path:
        """Write the table atomically as ``.npz``: 16-bit joint codes and the manifest.

        The codes span each joint's limits: steps below 2e-4 rad for a 4 pi range.
        """
        path = Path(path)
        rm = self.manifest['robot']
        with atomic_write(path) as tmp:
            np.savez(tmp, codes=range_codes(self.q, np.asarray(rm['lower']),
                                            np.asarray(rm['upper']), np.uint16),
                     manifest=np.array(json.dumps(self.manifest, sort_keys=True)))
        return path

    @classmethod
    def load(cls, path: Path, robot: Robot) -> 'SeedTable':
        """Read a table built for ``robot``.

        Raises:
            CorruptArtifact: unreadable, or its codes disagree with its manifest.
            ArtifactMismatch: a table of another robot.
        """
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as f:
                if 'codes' not in f or 'manifest' not in f:
                    raise CorruptArtifact(f'seed table {path} lacks its codes or manifest')
                codes, manifest = f['codes'], json.loads(str(f['manifest']))
        except CorruptArtifact:
            raise
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
            raise CorruptArtifact(f'cannot read seed table {path}: {exc}') from exc
        if not isinstance(manifest, dict) or manifest.get('kind') != 'sik_seed_table' \
                or not isinstance(manifest.get('robot'), dict):
            raise CorruptArtifact(f'{path} is not a sik_ros seed table')
        rm = manifest['robot']
        check_robot_manifest(f'seed table {path}', robot.manifest(), rm)
        for key in ('lower', 'upper'):  # the codes' ranges: the robot's own limits
            if rm.get(key) != getattr(robot, key).tolist():
                raise ArtifactMismatch(f'seed table {path}: joint {key} limits',
                                       getattr(robot, key).tolist(), rm.get(key))
        if codes.dtype != np.uint16 or codes.shape != (manifest.get('rows'), robot.dof) \
                or len(codes) == 0:
            raise CorruptArtifact(f'seed table {path}: codes disagree with its manifest')
        return cls(robot, range_values(codes, robot.lower, robot.upper), manifest)


def default_rows(robot: Robot) -> Optional[int]:
    """Seed-table rows a bundle of ``robot`` gets by default (None: no table).

    Arms of six joints or fewer: :data:`DEFAULT_ROWS`, the starts of their isolated pose
    solutions. 7-joint arms: :data:`~sik_ros.defaults.SEARCH_SEED_TABLE_ROWS`, the starts of
    the family search (:mod:`sik_ros.solver.families.search`). Others: none.
    """
    if robot.dof <= 6:
        return DEFAULT_ROWS
    return SEARCH_SEED_TABLE_ROWS if robot.dof == 7 else None
