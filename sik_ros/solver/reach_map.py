"""A reachability map: pose goals at every voxel of an arm's reach, solved by solve_batch.

The voxels of a cube about the first joint's origin whose centres lie within the arm's reach
radius (the chain's joint-to-joint distances summed: a bound no configuration exceeds, as each
distance is fixed by the link between the two joints) are kept; the others are plainly out of
reach and never solved. Each kept voxel's centre gets the same ``K`` orientations spread evenly
over SO(3) (super-Fibonacci spirals, Alexa 2022). The goals are solved in chunks of voxels; each
chunk is written to its own file (temporary name, then rename) beside a manifest of the
settings, so a stopped run continues with the chunks not yet written.
"""

from dataclasses import asdict, dataclass
import json
import math
from pathlib import Path
from typing import Callable, Dict, Optional

import numpy as np
import pinocchio as pin

from sik_ros.artifacts import atomic_write
from sik_ros.errors import ArtifactMismatch, CorruptArtifact, InvalidArgument

__all__ = ['ReachSettings', 'fibonacci_orientations', 'reach_radius', 'reach_voxels',
           'build_reach_map', 'load_reach_map']

#: The manifest's and the map's format.
REACH_FORMAT = 'sik-reach-v1'
#: The super-Fibonacci constants: sqrt(2) and the root of x^4 = x + 4 (Alexa 2022).
PHI, PSI = math.sqrt(2.0), 1.533751168755204288118041


@dataclass(frozen=True)
class ReachSettings:
    """A map's settings, kept in its manifest (a resumed run must match them).

    Attributes:
        voxel: voxel edge [m].
        orientations: orientations per voxel centre.
        num_solutions: solutions asked per goal (families are counted among them).
        timeout: each goal's budget [s] (None: none).
        chunk_goals: pose goals per chunk file (about).
    """

    voxel: float = 0.05
    orientations: int = 64
    num_solutions: int = 16
    timeout: Optional[float] = None
    chunk_goals: int = 2048


def fibonacci_orientations(count: int) -> np.ndarray:
    """``count`` unit quaternions (x, y, z, w) spread evenly over SO(3) (super-Fibonacci)."""
    if count < 1:
        raise InvalidArgument(f'orientations must be at least 1; got {count}')
    s = np.arange(count) + 0.5
    r, big = np.sqrt(s / count), np.sqrt(1.0 - s / count)
    alpha, beta = 2.0 * np.pi * s / PHI, 2.0 * np.pi * s / PSI
    return np.stack([r * np.sin(alpha), r * np.cos(alpha), big * np.sin(beta),
                     big * np.cos(beta)], axis=1)


def reach_radius(robot):
    """The first joint's origin in the base frame (3,) [m] and the arm's reach radius [m]."""
    q = 0.5 * (robot.lower + robot.upper)
    pin.framesForwardKinematics(robot.model, robot.data, q)
    base = robot.data.oMf[robot._base_id]
    points = [base.actInv(robot.data.oMi[j]).translation for j in range(1, robot.model.njoints)]
    points.append(robot.pin_placement(q).translation)
    points = np.array(points)
    return points[0], float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def reach_voxels(robot, voxel: float):
    """Centres (V, 3) [m] and grid indices (V, 3) of the voxels within the reach radius."""
    if not (isinstance(voxel, (int, float)) and math.isfinite(voxel) and voxel > 0):
        raise InvalidArgument(f'voxel must be a positive length [m]; got {voxel!r}')
    origin, radius = reach_radius(robot)
    half = int(math.ceil(radius / voxel))
    axis = np.arange(-half, half + 1)
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing='ij'), -1).reshape(-1, 3)
    centres = origin + (grid + 0.5) * voxel
    near = np.linalg.norm(centres - origin, axis=1) <= radius + voxel * math.sqrt(3) / 2
    return centres[near], grid[near]


def _manifest(ik, settings: ReachSettings, centres: np.ndarray, chunks: int) -> Dict:
    return dict(format=REACH_FORMAT, robot=ik.robot.name, joint_names=ik.joint_names,
                settings=asdict(settings), voxels=len(centres), chunks=chunks,
                centres_sum=float(np.round(centres.sum(), 6)))


def _write_npz(path: Path, **arrays) -> None:
    with atomic_write(path) as tmp:
        np.savez(tmp, **arrays)


def build_reach_map(ik, out: Path, settings: ReachSettings = ReachSettings(),
                    workers: Optional[int] = None,
                    progress: Optional[Callable[[int, int], None]] = None,
                    executor=None) -> Path:
    """Solve every pose goal of the map into ``out/reach.npz`` (resuming from its chunks).

    Args:
        ik: the solver (:class:`SelectiveIK`), with a pose-goal model.
        out: the map's folder (created; its manifest and chunks kept between runs).
        settings: voxel, orientations, solutions, timeout and chunk size.
        workers: processes of :meth:`SelectiveIK.solve_batch` (None: every core).
        progress: ``progress(goals_done, goals_total)`` after each chunk (and once at the
            start, chunks already written counted).
        executor: None, or a :class:`~sik_ros.solver.cluster.RayExecutor`: the goals solved
            on a Ray cluster (the same map: each goal's answer is the one ``solve`` gives).

    Returns:
        the path of ``reach.npz``: ``centers`` (V, 3), ``orientations`` (K, 4), ``success``
        (V, K) bool, ``families`` (V, K) uint16, ``reachability`` (V,), ``grid`` (V, 3),
        ``manifest``.

    Raises:
        ArtifactMismatch: ``out`` holds a map of other settings or another arm.
    """
    if 'pose' not in ik.goals:
        raise InvalidArgument('a reach map needs a bundle with a pose-goal model')
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    centres, grid = reach_voxels(ik.robot, settings.voxel)
    quats = fibonacci_orientations(settings.orientations)
    k = len(quats)
    per_chunk = max(1, settings.chunk_goals // k)
    chunks = -(-len(centres) // per_chunk)
    manifest = _manifest(ik, settings, centres, chunks)
    path = out / 'manifest.json'
    if path.exists():
        found = json.loads(path.read_text())
        if found != manifest:
            raise ArtifactMismatch(f'reach map in {out}', manifest, found)
    else:
        with atomic_write(path) as tmp:
            tmp.write_text(json.dumps(manifest, indent=2))
    success = np.zeros((len(centres), k), dtype=bool)
    families = np.zeros((len(centres), k), dtype=np.uint16)
    todo = []
    for c in range(chunks):
        rows = slice(c * per_chunk, min(len(centres), (c + 1) * per_chunk))
        part = _read_chunk(out / 'chunks' / f'{c:06d}.npz', rows.stop - rows.start, k)
        if part is None:
            todo.append((c, rows))
        else:
            success[rows], families[rows] = part
    (out / 'chunks').mkdir(exist_ok=True)
    total = len(centres) * k
    done = total - sum((r.stop - r.start) * k for _, r in todo)
    if progress:
        progress(done, total)
    for c, rows in todo:
        pos = np.repeat(centres[rows], k, 0)
        rot = np.tile(quats, (rows.stop - rows.start, 1))
        answers = ik.solve_batch(pos, rot, num_solutions=settings.num_solutions,
                                 timeout=settings.timeout, workers=workers,
                                 executor=executor)
        ok = np.array([a.success for a in answers]).reshape(-1, k)
        fam = np.array([a.num_families for a in answers], dtype=np.uint16).reshape(-1, k)
        _write_npz(out / 'chunks' / f'{c:06d}.npz', success=ok, families=fam)
        success[rows], families[rows] = ok, fam
        done += ok.size
        if progress:
            progress(done, total)
    target = out / 'reach.npz'
    _write_npz(target, centers=centres, orientations=quats, success=success,
               families=families, reachability=success.mean(axis=1), grid=grid,
               manifest=np.array(json.dumps(manifest)))
    return target


def _read_chunk(path: Path, rows: int, k: int):
    """A chunk's arrays, or None when it is missing or not of the expected shape."""
    try:
        with np.load(path) as data:
            ok, fam = data['success'], data['families']
    except (OSError, KeyError, ValueError):
        return None
    except Exception:  # a damaged archive: solved again
        return None
    return (ok, fam) if ok.shape == fam.shape == (rows, k) else None


def load_reach_map(path: Path) -> Dict[str, np.ndarray]:
    """A map's arrays, checked against its manifest.

    Raises:
        CorruptArtifact: unreadable, of another format, or arrays of the wrong shapes.
    """
    try:
        with np.load(path) as data:
            arrays = {name: data[name] for name in data.files}
        manifest = json.loads(str(arrays.pop('manifest')))
    except Exception as exc:  # any failure to read is a damaged file
        raise CorruptArtifact(f'cannot read reach map {path}: {exc}') from exc
    v, k = manifest.get('voxels'), manifest.get('settings', {}).get('orientations')
    if manifest.get('format') != REACH_FORMAT or arrays.get('success', np.empty(0)).shape != \
            (v, k) or arrays['centers'].shape != (v, 3) or arrays['families'].shape != (v, k):
        raise CorruptArtifact(f'reach map {path} does not match its manifest')
    arrays['manifest'] = manifest
    return arrays


def plot_reach_map(data: Dict, path: Path, slices: int = 4) -> Path:
    """``slices`` horizontal slices of the reachability through the map, as a PNG."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    grid, reach, centres = data['grid'], data['reachability'], data['centers']
    levels = np.unique(grid[:, 2])
    picks = levels[np.linspace(0, len(levels) - 1, slices + 2).round().astype(int)[1:-1]]
    fig, axes = plt.subplots(1, len(picks), figsize=(4 * len(picks), 4), squeeze=False)
    lo, hi = grid[:, :2].min(0), grid[:, :2].max(0)
    for ax, level in zip(axes[0], picks):
        rows = grid[:, 2] == level
        image = np.full((hi[1] - lo[1] + 1, hi[0] - lo[0] + 1), np.nan)
        image[grid[rows, 1] - lo[1], grid[rows, 0] - lo[0]] = reach[rows]
        voxel = data['manifest']['settings']['voxel']
        x0, y0 = centres[:, 0].min() - voxel / 2, centres[:, 1].min() - voxel / 2
        shown = ax.imshow(image, origin='lower', vmin=0, vmax=1, cmap='viridis',
                          extent=(x0, x0 + image.shape[1] * voxel, y0,
                                  y0 + image.shape[0] * voxel))
        ax.set_title(f'z = {centres[rows, 2].mean():.2f} m')
        ax.set_xlabel('x [m]')
        ax.set_ylabel('y [m]')
    fig.colorbar(shown, ax=axes[0].tolist(), label='fraction of orientations reached')
    with atomic_write(Path(path)) as tmp:
        fig.savefig(tmp, dpi=100)
    plt.close(fig)
    return Path(path)
