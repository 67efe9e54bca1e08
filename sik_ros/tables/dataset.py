"""Automated dataset collection (the paper's Algorithm 1) and dataset files.

A dataset is a directory of memory-mappable ``.npy`` arrays (``q``: joint positions [rad],
``position``: tip positions [m], ``quaternion``: tip orientations x y z w, all float64, one row per
configuration), a ``manifest.json`` and a human-readable ``stats.txt``.
"""

from dataclasses import dataclass
import math
from pathlib import Path
import shutil
import time
from typing import Callable, Dict, Iterator, List, Optional, Tuple, TYPE_CHECKING

import numpy as np

from sik_ros.artifacts import (atomic_directory, check_robot_manifest, FORMAT_VERSION,
                               library_versions, read_json, write_json_atomic)
from sik_ros.defaults import MAX_ROWS
from sik_ros.errors import CorruptArtifact, InvalidArgument
from sik_ros.kernels.angles import TURN
from sik_ros.kinematics.chain import chain_forward
from sik_ros.kinematics.rotations import rotation_to_quaternion

if TYPE_CHECKING:  # Pinocchio: a chain file's arm trains without it
    from sik_ros.kinematics.robot import Robot

ARRAYS = {'q': None, 'position': 3, 'quaternion': 4}
#: Edge of the cells used to report positions per cell in ``stats.txt`` [m].
STATS_CELL = 0.05


def grid_values(lower: np.ndarray, upper: np.ndarray, interval_deg: float,
                periodic: Optional[np.ndarray] = None) -> List[np.ndarray]:
    """Joint values of Algorithm 1: from each lower limit in steps while at or below the upper.

    A periodic joint (range of a turn or more) is swept over one turn only, centred in its
    range and without its end (``c - pi`` up to, not including, ``c + pi``): q and q + 2 pi are
    the same posture, which the solver adds back.

    Args:
        lower, upper: joint limits [rad].
        interval_deg: step [deg].
        periodic: which joints are periodic (default: none).

    Raises:
        InvalidArgument: a step that is not positive or larger than a joint's range.
    """
    if not math.isfinite(interval_deg) or interval_deg <= 0:
        raise InvalidArgument(f'interval must be a positive number of degrees; got {interval_deg}')
    step = math.radians(interval_deg)
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    periodic = np.zeros(len(lower), dtype=bool) if periodic is None else np.asarray(periodic)
    ranges = upper - lower
    too_big = [i for i, r in enumerate(ranges) if step > r + 1e-12]
    if too_big:
        i = too_big[0]
        raise InvalidArgument(
            f'interval {interval_deg} deg is larger than the range of joint {i + 1} '
            f'({math.degrees(ranges[i]):.2f} deg)')
    values = []
    for lo, hi, turn in zip(lower, upper, periodic):
        if turn:
            start = (lo + hi) / 2 - TURN / 2  # one turn about the middle of the range
            values.append(start + step * np.arange(math.ceil(TURN / step - 1e-9)))
        else:
            values.append(lo + step * np.arange(math.floor((hi - lo) / step + 1e-9) + 1))
    return values


def grid_count(lower: np.ndarray, upper: np.ndarray, interval_deg: float,
               periodic: Optional[np.ndarray] = None) -> int:
    """Number of configurations of the Algorithm 1 grid, without materialising it."""
    return int(np.prod([len(v) for v in grid_values(lower, upper, interval_deg, periodic)],
                       dtype=np.int64))


#: Intervals ``--interval auto`` chooses from [deg] (divisors of 360, finest first).
AUTO_INTERVALS = (5, 6, 8, 9, 10, 12, 15, 18, 20, 24, 30, 36, 40, 45, 60, 72, 90, 120, 180)


def finest_interval(robot: 'Robot', max_rows: int) -> Optional[float]:
    """The finest of :data:`AUTO_INTERVALS` whose grid has at most ``max_rows`` rows."""
    for interval in AUTO_INTERVALS:
        try:
            if grid_count(robot.lower, robot.upper, interval, robot.periodic) <= max_rows:
                return float(interval)
        except InvalidArgument:  # larger than a joint's range
            return None
    return None


def row_bytes(robot: 'Robot') -> int:
    """Bytes one dataset row takes on disk (float64 joints, position, quaternion)."""
    return 8 * (robot.dof + sum(c for c in ARRAYS.values() if c))


def check_budget(robot: 'Robot', rows: int, max_rows: int, disk_free: Optional[int] = None,
                 sampler: str = 'grid') -> None:
    """Refuse a collection above the row budget or the free disk space, with what would fit.

    Raises:
        InvalidArgument: naming the rows and the suggestions.
    """
    if rows > max_rows:
        fit = finest_interval(robot, max_rows)
        fit_rows = grid_count(robot.lower, robot.upper, fit, robot.periodic) if fit else 0
        grid = f'--interval {fit:g} ({fit_rows:,} rows) or --interval auto, ' if fit else ''
        raise InvalidArgument(
            f'{sampler} of {rows:,} rows is above the budget of {max_rows:,} (--max-rows); '
            f'try {grid}or --sampler uniform --samples {min(max_rows, 5_000_000):,}')
    need = rows * row_bytes(robot)
    if disk_free is not None and need > 0.95 * disk_free:
        raise InvalidArgument(f'{rows:,} rows need {need / 1e9:.2f} GB; only '
                              f'{disk_free / 1e9:.2f} GB are free there')


def estimate_seconds(robot: 'Robot', rows: int, probe: int = 1 << 14) -> float:
    """Seconds a collection of ``rows`` rows takes here, from timing FK of ``probe`` rows."""
    q = np.random.default_rng(0).uniform(robot.lower, robot.upper, (probe, robot.dof))
    t0 = time.perf_counter()
    robot.fk_batch(q)
    return (time.perf_counter() - t0) / probe * rows


def free_disk(path: Path) -> int:
    """Free bytes on the file system that holds ``path`` (or its nearest existing parent)."""
    path = Path(path).resolve()
    while not path.exists() and path != path.parent:
        path = path.parent
    return shutil.disk_usage(path).free


def _cartesian(values: List[np.ndarray]) -> np.ndarray:
    """All combinations of per-joint values, first joint slowest, as (N, len(values))."""
    if not values:
        return np.zeros((1, 0))
    mesh = np.meshgrid(*values, indexing='ij')
    return np.stack([m.reshape(-1) for m in mesh], axis=1)


Chunk = Tuple[np.ndarray, np.ndarray, np.ndarray]


def iter_grid(robot: 'Robot', interval_deg: float, chunk: int = 1 << 18) -> Iterator[Chunk]:
    """Yield ``(q, position, quaternion)`` chunks of the grid, in row order.

    The transforms of the leading joints are shared by many rows, so they are computed once per
    prefix and only the last two joints are evaluated per row.
    """
    values = grid_values(robot.lower, robot.upper, interval_deg, robot.periodic)
    n_tail = min(2, robot.dof)
    head, tail = values[:robot.dof - n_tail], values[robot.dof - n_tail:]
    q_head = _cartesian(head)
    q_tail = _cartesian(tail)
    if head:
        head_p, head_r = chain_forward(robot.chain, q_head, tip=False)
    else:
        head_p = np.broadcast_to(robot.chain.base_translation, (1, 3))
        head_r = np.broadcast_to(robot.chain.base_rotation, (1, 3, 3))
    per = max(1, chunk // len(q_tail))
    for s in range(0, len(q_head), per):
        e = min(s + per, len(q_head))
        m = e - s
        start = (np.repeat(head_p[s:e], len(q_tail), axis=0),
                 np.repeat(head_r[s:e], len(q_tail), axis=0))
        qt = np.tile(q_tail, (m, 1))
        p, r = chain_forward(robot.chain, qt, first=robot.dof - n_tail, start=start)
        q = np.concatenate([np.repeat(q_head[s:e], len(q_tail), axis=0), qt], axis=1)
        yield q, p, rotation_to_quaternion(r)


def iter_uniform(robot: 'Robot', samples: int, seed: int,
                 chunk: int = 1 << 18) -> Iterator[Chunk]:
    """Yield chunks of configurations drawn uniformly within the joint limits."""
    if samples < 1:
        raise InvalidArgument(f'samples must be at least 1; got {samples}')
    rng = np.random.default_rng(seed)
    for s in range(0, samples, chunk):
        q = rng.uniform(robot.lower, robot.upper, size=(min(chunk, samples - s), robot.dof))
        p, quat = robot.fk_batch(q)
        yield q, p, quat


@dataclass
class Dataset:
    """A loaded dataset: memory-mapped arrays and their manifest."""

    path: Path
    manifest: dict
    q: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray

    def __len__(self) -> int:
        """Number of rows."""
        return len(self.q)

    @classmethod
    def load(cls, path: Path, robot: Optional['Robot'] = None, mmap: bool = True) -> 'Dataset':
        """Open a dataset directory, checking its manifest and arrays.

        Args:
            path: dataset directory written by :func:`collect`.
            robot: when given, the dataset must have been collected on this robot.
            mmap: memory-map the arrays instead of reading them.

        Raises:
            CorruptArtifact: missing manifest, missing or truncated arrays, wrong sizes.
            ArtifactMismatch: a dataset of another robot, URDF or frames.
        """
        path = Path(path)
        manifest = read_json(path / 'manifest.json', f'dataset {path}')
        if not isinstance(manifest, dict) or manifest.get('kind') != 'dataset':
            kind = manifest.get('kind') if isinstance(manifest, dict) else type(manifest).__name__
            raise CorruptArtifact(f'{path} is not a sik_ros dataset (kind={kind})')
        count, rm = manifest.get('count'), manifest.get('robot')
        if isinstance(count, bool) or not isinstance(count, int) or count < 1 or not \
                isinstance(rm, dict) or not isinstance(rm.get('joint_names'), list):
            raise CorruptArtifact(f'dataset {path}/manifest.json needs a row count >= 1 and a '
                                  f'robot manifest with joint_names')
        if robot is not None:
            check_robot_manifest(f'dataset {path}', robot.manifest(), rm)
        dof = len(rm['joint_names'])
        arrays = {}
        for name, cols in ARRAYS.items():
            file = path / f'{name}.npy'
            try:
                arr = np.load(file, mmap_mode='r' if mmap else None)
            except (OSError, ValueError) as exc:
                raise CorruptArtifact(f'dataset {path}: cannot read {file.name}: {exc}') from exc
            shape = (count, cols if cols else dof)
            if arr.shape != shape:
                raise CorruptArtifact(
                    f'dataset {path}: {file.name} has shape {arr.shape}, manifest says {shape}')
            if arr.dtype != np.float64:
                raise CorruptArtifact(f'dataset {path}: {file.name} holds {arr.dtype}, not '
                                      f'float64')
            for s in range(0, count, 1 << 20):
                if not np.all(np.isfinite(arr[s:s + (1 << 20)])):
                    raise CorruptArtifact(f'dataset {path}: {file.name} has non-finite values')
            arrays[name] = arr
        return cls(path, manifest, **arrays)


def sampled(robot: 'Robot', sampler: str, interval_deg: float, samples: int, seed: int,
            chunk: int):
    """A collection's row count, its chunks ``(q, p, quat)`` and its sampler parameters.

    Raises:
        InvalidArgument: an unknown sampler, or fewer than one uniform sample.
    """
    if sampler == 'grid':
        return (grid_count(robot.lower, robot.upper, interval_deg, robot.periodic),
                iter_grid(robot, interval_deg, chunk), {'interval_deg': interval_deg})
    if sampler == 'uniform':
        if samples < 1:
            raise InvalidArgument(f'--samples must be at least 1; got {samples}')
        params = {'samples': samples, 'seed': seed}
        return samples, iter_uniform(robot, samples, seed, chunk), params
    raise InvalidArgument(f'unknown sampler {sampler!r}; use grid or uniform')


def collect(robot: 'Robot', out: Path, sampler: str = 'grid', interval_deg: float = 30.0,
            samples: int = 0, seed: int = 0, force: bool = False,
            progress: Optional[Callable[[int], None]] = None, chunk: int = 1 << 18,
            max_rows: int = MAX_ROWS) -> Dataset:
    """Collect a dataset of tip poses and write it atomically to ``out``.

    Args:
        robot: the arm.
        out: output directory (must not exist unless ``force``).
        sampler: ``grid`` (Algorithm 1) or ``uniform``.
        interval_deg: grid step [deg].
        samples: number of uniform samples.
        seed: random seed of the uniform sampler.
        force: replace an existing ``out``.
        progress: called with the number of rows written after each chunk.
        chunk: rows computed at a time.
        max_rows: refuse (before writing anything) a collection of more rows.

    Returns:
        the dataset, loaded from its final location.
    """
    count, chunks, params = sampled(robot, sampler, interval_deg, samples, seed, chunk)
    check_budget(robot, count, max_rows, free_disk(out), sampler)
    with atomic_directory(out, force=force) as tmp:
        arrays = {
            name: np.lib.format.open_memmap(tmp / f'{name}.npy', mode='w+', dtype=np.float64,
                                            shape=(count, cols if cols else robot.dof))
            for name, cols in ARRAYS.items()}
        row = 0
        for q, p, quat in chunks:
            n = len(q)
            arrays['q'][row:row + n] = q
            arrays['position'][row:row + n] = p
            arrays['quaternion'][row:row + n] = quat
            row += n
            if progress:
                progress(n)
        if row != count:
            raise CorruptArtifact(f'internal error: wrote {row} rows, expected {count}')
        _sanity_check(robot, arrays['q'])
        stats = dataset_stats(robot, arrays['q'], arrays['position'])
        for arr in arrays.values():
            arr.flush()
        del arrays
        manifest = {
            'kind': 'dataset', 'format_version': FORMAT_VERSION, 'robot': robot.manifest(),
            'sampler': sampler, 'params': params, 'count': count, 'seed': seed,
            'dtype': 'float64', 'arrays': {k: f'{k}.npy' for k in ARRAYS},
            'versions': library_versions(), 'stats': stats,
        }
        (tmp / 'stats.txt').write_text(format_stats(robot, manifest))
        write_json_atomic(tmp / 'manifest.json', manifest)
    return Dataset.load(out, robot)


def _sanity_check(robot: 'Robot', q: np.ndarray, block: int = 1 << 20) -> None:
    """Refuse data outside the joint limits or with a joint that never moves."""
    lo = np.full(robot.dof, np.inf)
    hi = np.full(robot.dof, -np.inf)
    for s in range(0, len(q), block):
        lo = np.minimum(lo, q[s:s + block].min(axis=0))
        hi = np.maximum(hi, q[s:s + block].max(axis=0))
    eps = 1e-9
    if np.any(lo < robot.lower - eps) or np.any(hi > robot.upper + eps):
        raise CorruptArtifact('collected joint values fall outside the joint limits')
    if len(q) > 1 and np.any(hi - lo <= 0):
        stuck = [robot.joint_names[i] for i in np.flatnonzero(hi - lo <= 0)]
        raise CorruptArtifact(f'degenerate dataset: joints {stuck} never move')


def dataset_stats(robot: 'Robot', q: np.ndarray, position: np.ndarray) -> dict:
    """Ranges, reach, distinct positions and positions per cell of a dataset."""
    pos = np.asarray(position)
    reach = np.linalg.norm(pos, axis=1)
    key_um = np.round(pos * 1e5).astype(np.int64) + (1 << 20)
    keys = (key_um[:, 0] << 42) | (key_um[:, 1] << 21) | key_um[:, 2]
    distinct = int(len(np.unique(keys)))
    cells = np.floor(pos / STATS_CELL).astype(np.int64) + (1 << 20)
    cell_keys = (cells[:, 0] << 42) | (cells[:, 1] << 21) | cells[:, 2]
    _, per_cell = np.unique(cell_keys, return_counts=True)
    return {
        'rows': int(len(pos)),
        'q_min': np.asarray(q).min(axis=0).tolist(),
        'q_max': np.asarray(q).max(axis=0).tolist(),
        'position_min': pos.min(axis=0).tolist(),
        'position_max': pos.max(axis=0).tolist(),
        'reach_max': float(reach.max()),
        'reach_mean': float(reach.mean()),
        'distinct_positions_10um': distinct,
        'cell_size': STATS_CELL,
        'occupied_cells': int(len(per_cell)),
        'rows_per_cell': {'min': int(per_cell.min()), 'median': float(np.median(per_cell)),
                          'max': int(per_cell.max())},
    }


def format_stats(robot: 'Robot', manifest: dict) -> str:
    """The human-readable ``stats.txt`` of a dataset."""
    st = manifest['stats']
    lines = [f"sik_ros dataset: {manifest['robot']['robot']} "
             f"({manifest['robot']['base_frame']} -> {manifest['robot']['tip_frame']})",
             f"sampler: {manifest['sampler']} {manifest['params']}",
             f"rows: {st['rows']}",
             f"distinct tip positions (10 um): {st['distinct_positions_10um']}",
             f"reach: max {st['reach_max']:.4f} m, mean {st['reach_mean']:.4f} m",
             'position range [m]: ' + ', '.join(
                 f'{a} {lo:+.3f}..{hi:+.3f}' for a, lo, hi in
                 zip('xyz', st['position_min'], st['position_max'])),
             f"rows per {st['cell_size'] * 100:.0f} cm cell: min {st['rows_per_cell']['min']}, "
             f"median {st['rows_per_cell']['median']:.0f}, max {st['rows_per_cell']['max']} "
             f"({st['occupied_cells']} cells)",
             'joint ranges [rad]:']
    for name, lo, hi in zip(robot.joint_names, st['q_min'], st['q_max']):
        lines.append(f'  {name}: {lo:+.4f} .. {hi:+.4f}')
    return '\n'.join(lines) + '\n'


def dataset_summary(ds: Dataset) -> Dict:
    """The parts of a dataset manifest a checkpoint records."""
    m = ds.manifest
    return {'sampler': m['sampler'], 'params': m['params'], 'count': m['count'],
            'robot': m['robot']['robot'], 'urdf_sha256': m['robot']['urdf_sha256']}
