"""The paper's experiments as functions returning plain dicts and arrays (no printing).

Sections of the paper's "Experiments" and the function for each:

1. distance error over the workspace and per radius: :func:`workspace_targets`,
   :func:`sphere_targets`, :func:`distance_errors`;
2. computing time per solution: :func:`timing_study` (with TRAC-IK, :class:`TracIK`);
3. diversity of ten far-apart postures per target: :func:`diversity_study`;
4. posture indices: :func:`latent_study` (a training study, read from checkpoints) and
   :func:`element_sweep`;
5. orientation as goal: :func:`orientation_study`;
6. obstacle avoidance with Algorithm 2: :func:`obstacle_study`.

Every distance error here is recomputed from the joint angles by forward kinematics: the distance
between the target and the tip the angles reach [m].
"""

from dataclasses import dataclass
import os
from pathlib import Path
import platform
import re
import time
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np
from scipy.spatial.transform import Rotation
import torch

from sik_ros.artifacts import check_robot_manifest
from sik_ros.errors import ArtifactMismatch, CorruptArtifact
from sik_ros.index_table import farthest_point_subset
from sik_ros.kinematics import chain_forward, Robot
from sik_ros.models import make_goal
from sik_ros.objectives import Obstacle
from sik_ros.solver import SelectiveIK
from sik_ros.training import load_checkpoint, model_from_checkpoint

Progress = Optional[Callable[[int], None]]

#: Radii of the per-radius table, around the base origin [m] (paper: 5 to 90 cm).
RADII = tuple(round(0.05 * k, 2) for k in range(1, 19))
#: The paper's four targets of "Distance error in different postures" (a to d) [m].
DIVERSITY_TARGETS = ((0.1357, -0.321, 0.222), (-0.333, 0.246, 0.1999),
                     (-0.188, -0.168, 0.321), (0.2020, 0.2021, 0.2022))
#: Target of the paper's element sweep (Table 5) [m].
SWEEP_TARGET = (-0.25, -0.25, 0.25)
#: Baseline files looked for in a ``--baselines`` directory.
BASELINE_FILES = {'psik': 'psik.pt', 'fcn': 'fcn.pt', 'fcn_uni': 'fcn_uni.pt',
                  'anfis': 'anfis.pt'}
BASELINE_KINDS = {'psik': 'psik', 'fcn': 'fcn', 'fcn_uni': 'fcn', 'anfis': 'anfis'}

#: The paper's figures (cm, ms, deg^2), copied from its text and tables.
PAPER = {
    'workspace_cm': {'sik': 0.5, 'psik': 1.7, 'fcn': 45.0, 'fcn_uni': 40.0, 'anfis': 70.0},
    'radius_cm': {
        'sik': (1.84, 1.87, 0.42, 0.44, 0.73, 0.47, 0.71, 0.63, 0.58, 0.68, 0.64, 0.64, 0.84,
                0.65, 0.73, 0.83, 1.15, 0.88),
        'psik': (1.31, 2.16, 1.22, 1.21, 2.36, 1.15, 1.35, 1.34, 1.31, 1.78, 1.90, 1.61, 1.6,
                 2.18, 2.16, 1.86, 2.45, 2.11),
        'anfis': (91.1, 88.6, 88.2, 85.8, 82.2, 82.5, 75.9, 76.5, 74.7, 70.1, 70.3, 71.3, 68.3,
                  66.2, 66.5, 62.9, 60.5, 68.4),
        'fcn': (26.2, 23.9, 28.6, 27.4, 29.0, 29.9, 30.5, 37.1, 40.6, 35.3, 41.8, 50.9, 59.5,
                56.4, 66.2, 70.0, 76.3, 80.0),
        'fcn_uni': (18.6, 18.8, 18.6, 19.2, 22.2, 22.8, 26.4, 32.1, 31.3, 40.1, 40.6, 41.7,
                    57.9, 59.6, 67.9, 66.5, 76.9, 80.5),
    },
    'radius_avg_cm': {'sik': 0.82, 'psik': 1.73, 'anfis': 75.0, 'fcn': 45.0, 'fcn_uni': 41.2},
    'time_ms': {'sik': 4.0, 'psik': 4.0, 'fcn': 3.0, 'anfis': 0.15},
    'variance_deg2': {
        'sik': ((141.23, 70.59, 175.55, 5.75, 178.47, 54.69, 133.93),
                (194.92, 56.36, 188.62, 15.60, 213.78, 147.51, 114.54),
                (166.66, 99.60, 176.19, 2.99, 142.76, 109.93, 51.89),
                (110.25, 57.55, 255.89, 1.25, 335.27, 131.81, 126.34)),
        'psik': ((138.53, 70.26, 176.80, 5.69, 179.89, 54.97, 0.01),
                 (205.18, 56.01, 159.10, 17.50, 249.05, 121.48, 71.94),
                 (164.97, 98.49, 178.18, 3.03, 142.63, 109.57, 0.01),
                 (172.87, 55.37, 249.41, 1.28, 341.17, 131.19, 1.50)),
    },
    'diversity_cm': {
        'sik': ((0.22, 0.25, 0.54, 0.22, 0.31, 1.6, 0.29, 0.56, 0.19, 0.61),
                (0.35, 0.25, 0.48, 0.4, 0.36, 0.38, 0.42, 0.4, 0.34, 0.35),
                (0.74, 0.24, 1.04, 0.57, 0.40, 0.63, 0.43, 0.45, 0.31, 0.61),
                (0.21, 0.29, 0.31, 0.47, 1.08, 0.30, 0.46, 0.40, 0.46, 0.71)),
        'psik': ((0.98, 0.65, 1.03, 0.82, 1.70, 1.28, 3.24, 0.63, 1.20, 2.72),
                 (0.93, 1.51, 1.46, 2.44, 1.32, 0.40, 0.74, 1.48, 1.13, 1.83),
                 (0.94, 1.45, 3.35, 1.26, 0.51, 1.64, 0.77, 1.09, 0.29, 0.63),
                 (1.03, 0.27, 1.04, 2.18, 2.05, 1.31, 1.18, 1.39, 2.94, 1.17)),
    },
    'sweep_cm': ((0.08, 0.24, 0.6, 0.81, 0.65, 0.51), (0.06, 0.15, 0.18, 0.08, 0.49, 0.6),
                 (0.03, 0.58, 0.66, 0.38, 0.37, 0.38), (0.03, 0.11, 0.18, 0.19, 0.42, 0.86)),
    'orientation': {'distance_cm': 1.35, 'cosine': 0.9983},
}


# -- helpers --------------------------------------------------------------------------------------

def arm_points(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Base origin, joint origins and tip of configurations (N, n): (N, n + 2, 3) [m]."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    tip, _, origins, _ = chain_forward(robot.chain, q, frames=True)
    base = np.zeros((len(q), 1, 3))
    return np.concatenate([base, origins, tip[:, None]], axis=1)


def position_errors(robot: Robot, q: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Distance errors [m] of configurations (N, n) against targets (N, 3) or (3,), by FK."""
    p, _ = robot.fk_rot(np.atleast_2d(q))
    return np.linalg.norm(p - np.asarray(targets, dtype=float), axis=1)


def orientation_cosine(rot_target: np.ndarray, rot: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Cosine similarity and angle [rad] between a target rotation (3, 3) and rotations (N, 3, 3).

    The cosine similarity is the mean over the three axes (matrix columns) of the cosine between
    the target axis and the reached one, i.e. ``trace(R_t^T R) / 3 = (1 + 2 cos(angle)) / 3``.
    """
    cos_axes = np.einsum('ij,nij->nj', rot_target, rot)
    angle = np.arccos(np.clip((cos_axes.sum(axis=1) - 1) / 2, -1.0, 1.0))
    return cos_axes.mean(axis=1), angle


def machine_info() -> Dict:
    """Platform, processor, cores and library versions of this run."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path('/proc/cpuinfo').read_text().splitlines():
            if line.startswith('model name'):
                cpu = line.split(':', 1)[1].strip()
                break
    except OSError:
        pass
    load = os.getloadavg() if hasattr(os, 'getloadavg') else (float('nan'),) * 3
    return {'platform': platform.platform(), 'cpu': cpu, 'cores': os.cpu_count(),
            'torch_threads': torch.get_num_threads(), 'python': platform.python_version(),
            'torch': str(torch.__version__), 'load_average': [round(v, 2) for v in load]}


# -- baselines ------------------------------------------------------------------------------------

@dataclass
class _GoalModel:
    """What :class:`SelectiveIK` needs per goal kind (model, config, normaliser, table)."""

    model: torch.nn.Module
    cfg: object
    norm: object
    table: object


class PriorTable:
    """Index candidates for a PSIK model that comes without a table: draws from its prior.

    PSIK's posture indices are trained towards N(0, I), so a fixed set of draws (the same for
    every target) stands in for the table's indices near the target.
    """

    def __init__(self, latent_dim: int, count: int = 48, seed: int = 0):
        rng = np.random.default_rng(seed)
        self.indices = rng.standard_normal((count, latent_dim)).astype(np.float32)
        self.latent_dim = latent_dim

    def __len__(self) -> int:
        """One pseudo-cell."""
        return 1

    def candidates(self, position: np.ndarray, k_cells: int = 8) -> np.ndarray:
        """The fixed prior draws, whatever the position, (count, latent)."""
        return self.indices.copy()

    @property
    def index_bounds(self):
        """Element-wise (min, max) of the draws."""
        return self.indices.min(axis=0), self.indices.max(axis=0)


class Baseline:
    """A single-solution model (FCN or ANFIS): position [m] -> joint angles [rad]."""

    def __init__(self, name: str, path: Path, robot: Robot):
        ckpt = load_checkpoint(path)
        check_robot_manifest(f'baseline {path}', robot.manifest(), ckpt['robot'])
        self.model, self.cfg, self.norm = model_from_checkpoint(ckpt)
        if self.cfg.goal != 'position':
            raise ArtifactMismatch(f'baseline {path}: goal', 'position', self.cfg.goal)
        self.name, self.path, self.robot = name, Path(path), robot
        self.train_config = ckpt.get('train_config', {})
        self.history = ckpt.get('history', [])
        self.step = int(ckpt.get('step', 0))

    @torch.no_grad()
    def predict(self, positions: np.ndarray) -> np.ndarray:
        """Joint angles (N, n) [rad], clipped to the limits, for positions (N, 3) [m]."""
        goal = make_goal('position', np.atleast_2d(positions), None).astype(np.float32)
        x = self.model(self.norm.goal_to_net(torch.from_numpy(goal)))
        q = self.norm.q_from_net(x).double().numpy()
        return np.clip(q, self.robot.lower, self.robot.upper)


def load_baselines(directory: Optional[Path], robot: Robot) -> Tuple[Dict, Dict[str, str]]:
    """The baselines found in a directory, and why each missing one is missing.

    ``psik/`` (a bundle with its own table) is preferred over ``psik.pt`` (a model whose
    candidate indices are then drawn from its prior, see :class:`PriorTable`); ``fcn.pt``,
    ``fcn_uni.pt`` and ``anfis.pt`` are :class:`Baseline` models.

    Returns:
        ``({name: SelectiveIK or Baseline}, {name: reason it is absent})``.
    """
    found, missing = {}, {}
    for name, fname in BASELINE_FILES.items():
        path = None if directory is None else Path(directory) / fname
        if name == 'psik' and directory is not None and (Path(directory) / 'psik').is_dir():
            ik = SelectiveIK.load(Path(directory) / 'psik')
            found[name] = ik
            continue
        if path is None or not path.is_file():
            missing[name] = 'not provided' if directory is None else f'not provided ({path})'
            continue
        try:
            if name == 'psik':
                found[name] = psik_solver(path, robot)
            else:
                base = Baseline(name, path, robot)
                if base.cfg.kind != BASELINE_KINDS[name]:
                    raise ArtifactMismatch(f'baseline {path}: kind', BASELINE_KINDS[name],
                                           base.cfg.kind)
                found[name] = base
        except (CorruptArtifact, ArtifactMismatch) as exc:
            missing[name] = f'refused: {exc}'
    return found, missing


def psik_solver(path: Path, robot: Robot, count: int = 48) -> SelectiveIK:
    """A :class:`SelectiveIK` over a PSIK checkpoint, its indices drawn from the prior."""
    ckpt = load_checkpoint(path)
    check_robot_manifest(f'baseline {path}', robot.manifest(), ckpt['robot'])
    model, cfg, norm = model_from_checkpoint(ckpt)
    if cfg.kind != 'psik' or cfg.goal != 'position':
        raise ArtifactMismatch(f'baseline {path}: kind/goal', 'psik/position',
                               f'{cfg.kind}/{cfg.goal}')
    table = PriorTable(cfg.latent_dim, count)
    return SelectiveIK(robot, {'position': _GoalModel(model, cfg, norm, table)},
                       bundle=Path(path))


# -- 1. distance error ----------------------------------------------------------------------------

def workspace_targets(robot: Robot, count: int, seed: int = 0) -> Tuple[np.ndarray, np.ndarray]:
    """Targets uniform over the workspace: FK of joint angles uniform within the limits.

    Returns:
        positions (count, 3) [m] and the configurations (count, n) that reach them.
    """
    rng = np.random.default_rng(seed)
    q = rng.uniform(robot.lower, robot.upper, (count, robot.dof))
    return robot.fk_rot(q)[0], q


def sphere_targets(robot: Robot, radii: Sequence[float] = RADII, per_radius: int = 100,
                   samples: int = 1_000_000, tol: float = 0.01, seed: int = 1,
                   chunk: int = 200_000) -> Dict[float, Dict[str, np.ndarray]]:
    """Reachable targets near spheres around the base origin.

    Draws ``samples`` joint configurations uniformly within the limits, keeps the tips whose
    distance from the base origin is within ``tol`` of a radius, and picks ``per_radius`` of them
    at random (all of them when fewer exist).

    Returns:
        ``{radius: {'positions': (k, 3), 'q': (k, n), 'available': int}}``.
    """
    rng = np.random.default_rng(seed)
    radii = np.asarray(radii, dtype=float)
    pos_parts, q_parts = [], []
    for start in range(0, samples, chunk):
        q = rng.uniform(robot.lower, robot.upper, (min(chunk, samples - start), robot.dof))
        p, _ = robot.fk_rot(q)
        near = np.abs(np.linalg.norm(p, axis=1)[:, None] - radii[None]).min(axis=1) < tol
        pos_parts.append(p[near])
        q_parts.append(q[near])
    pos, qs = np.concatenate(pos_parts), np.concatenate(q_parts)
    dist = np.linalg.norm(pos, axis=1)
    out = {}
    for r in radii:
        rows = np.flatnonzero(np.abs(dist - r) < tol)
        pick = rng.permutation(rows)[:per_radius]
        out[float(r)] = {'positions': pos[pick], 'q': qs[pick], 'available': int(len(rows))}
    return out


def sik_errors(ik: SelectiveIK, targets: np.ndarray, progress: Progress = None,
               num_raw: int = 10) -> Dict[str, np.ndarray]:
    """Distance errors [m] of a SelectiveIK (SIK or PSIK) on position targets.

    Returns:
        per target: ``raw_first`` (first-ranked solution of ``solve(refine=False)``),
        ``raw_mean`` (mean over its up to ``num_raw`` solutions), ``raw_count`` (how many it
        returned), ``refined`` (first-ranked solution of ``solve(refine=True)``).
    """
    keys = ('raw_first', 'raw_mean', 'raw_count', 'refined')
    out = {k: np.empty(len(targets)) for k in keys}
    for i, p in enumerate(np.asarray(targets, dtype=float)):
        raw = ik.solve(p, num_solutions=num_raw, refine=False)
        q_raw = np.array([s.q for s in raw.solutions])
        e_raw = position_errors(ik.robot, q_raw, p)
        ref = ik.solve(p, num_solutions=1, refine=True)
        out['raw_first'][i] = e_raw[0]
        out['raw_mean'][i] = e_raw.mean()
        out['raw_count'][i] = len(e_raw)
        out['refined'][i] = position_errors(ik.robot, ref.solutions[0].q, p)[0]
        if progress:
            progress(1)
    return out


def baseline_errors(base: Baseline, targets: np.ndarray) -> np.ndarray:
    """Distance errors [m] of a single-solution baseline's predictions, (N,)."""
    targets = np.asarray(targets, dtype=float)
    return position_errors(base.robot, base.predict(targets), targets)


def model_errors(model, targets: np.ndarray, progress: Progress = None) -> Dict[str, np.ndarray]:
    """Per-target errors of a SelectiveIK (see :func:`sik_errors`) or a baseline (``raw``)."""
    if isinstance(model, SelectiveIK):
        return sik_errors(model, targets, progress)
    errs = {'raw': baseline_errors(model, targets)}
    if progress:
        progress(len(targets))
    return errs


def distance_error_study(ik: SelectiveIK, baselines: Dict, workspace: np.ndarray,
                         spheres: Dict[float, Dict], progress: Progress = None) -> Dict:
    """Experiment 1: mean distance errors over the workspace and per radius, every model.

    Args:
        ik: the SIK solver (position goals).
        baselines: ``{name: SelectiveIK or Baseline}`` (see :func:`load_baselines`).
        workspace: targets uniform over the workspace (N, 3) [m].
        spheres: output of :func:`sphere_targets`.

    Returns:
        ``{'workspace': {model: {variant: per-target errors}}, 'radius': {model: {variant:
        [per-target errors per radius]}}}``, errors in metres.
    """
    models = {'sik': ik, **baselines}
    out = {'workspace': {}, 'radius': {}}
    for name, model in models.items():
        out['workspace'][name] = model_errors(model, workspace, progress)
        per = {}
        for r in spheres:
            for variant, e in model_errors(model, spheres[r]['positions'], progress).items():
                per.setdefault(variant, []).append(e)
        out['radius'][name] = per
    return out


# -- 2. computing time ----------------------------------------------------------------------------

class TracIK:
    """TRAC-IK through pytracik: full pose goals, 5 ms timeout, eps 1e-5, Speed mode."""

    def __init__(self, robot: Robot, timeout: float = 0.005):
        import pytracik
        self._ik = pytracik.ik
        self.robot = robot
        self.solver = pytracik.TRAC_IK(robot.base_frame, robot.tip_frame,
                                       robot.urdf_path.read_text(), timeout, 1e-5,
                                       pytracik.SolveType.Speed)
        pytracik.set_joint_limits(self.solver, list(robot.lower), list(robot.upper))

    def solve(self, position: np.ndarray, quat: np.ndarray, q0: np.ndarray):
        """One solve from ``q0`` towards a pose (quaternion x y z w); returns (ok, q)."""
        out = self._ik(self.solver, np.asarray(q0, dtype=float), *position, *quat)
        q = np.asarray(out[1:], dtype=float)
        ok = out[0] >= 0 and np.all(q >= self.robot.lower - 1e-9) and \
            np.all(q <= self.robot.upper + 1e-9)
        return bool(ok), q


def _time_calls(fn: Callable, items: Sequence, progress: Progress = None) -> Dict:
    """Wall time of ``fn(item)`` per item after one warm-up call; ``fn`` returns a count."""
    fn(items[0])
    times, counts = [], []
    for item in items:
        t0 = time.perf_counter()
        counts.append(fn(item))
        times.append(time.perf_counter() - t0)
        if progress:
            progress(1)
    times, counts = np.array(times), np.array(counts, dtype=float)
    per_solution = times / np.maximum(counts, 1)
    return {'calls': len(items), 'median_ms': 1e3 * float(np.median(times)),
            'mean_ms': 1e3 * float(times.mean()),
            'solutions_per_call': float(counts.mean()),
            'per_solution_ms': 1e3 * float(np.median(per_solution))}


def timing_study(ik: SelectiveIK, baselines: Dict, positions: np.ndarray,
                 quats: np.ndarray, tracik: Optional[TracIK] = None, seed: int = 0,
                 progress: Progress = None) -> Dict[str, Dict]:
    """Experiment 2: wall time per call and per solution of every method, in one run.

    SIK/PSIK solutions count the solutions a call returns; the single-solution methods return
    one (TRAC-IK: one when it succeeds within its timeout, from a random seed).

    Returns:
        ``{method: {'median_ms', 'mean_ms', 'solutions_per_call', 'per_solution_ms', ...}}``.
    """
    out = {}
    items = list(np.asarray(positions, dtype=float))
    solvers = {'sik': ik, **{k: v for k, v in baselines.items() if isinstance(v, SelectiveIK)}}
    for name, s in solvers.items():
        z0 = s.models['position'].table.candidates(items[0], 1)[:1]
        out[f'{name}_decode'] = _time_calls(
            lambda p, s=s, z0=z0: len(s.decode('position', p, None, z0)), items, progress)
        for num in (1, 10):
            for refine in (False, True):
                key = f'{name}_{"refined" if refine else "raw"}_{num}'
                out[key] = _time_calls(
                    lambda p, s=s, n=num, r=refine: len(
                        s.solve(p, num_solutions=n, refine=r).solutions), items, progress)
    for name, b in baselines.items():
        if isinstance(b, Baseline):
            out[name] = _time_calls(lambda p, b=b: len(b.predict(p[None])), items, progress)
    if tracik is not None:
        rng = np.random.default_rng(seed)
        seeds = rng.uniform(ik.robot.lower, ik.robot.upper, (len(items), ik.robot.dof))
        ok = []

        def run(i):
            good, _ = tracik.solve(items[i], quats[i], seeds[i])
            ok.append(good)
            return int(good)
        rec = _time_calls(run, list(range(len(items))), progress)
        rec['success'] = float(np.mean(ok[1:]))
        # time spent per solution found: all the calls' time over the successful ones
        rec['per_solution_ms'] = rec['mean_ms'] / max(rec['success'], 1e-9)
        out['tracik'] = rec
    return out


# -- 3. diversity ---------------------------------------------------------------------------------

def far_apart_indices(ik: SelectiveIK, position: np.ndarray, count: int,
                      goal: str = 'position') -> np.ndarray:
    """``count`` far-apart posture indices from the table cells near a position."""
    pool = ik.models[goal].table.candidates(np.asarray(position, dtype=float), ik.config.k_cells)
    return pool[farthest_point_subset(pool, count)]


def diversity_study(ik: SelectiveIK, targets: Sequence = DIVERSITY_TARGETS,
                    count: int = 10) -> List[Dict]:
    """Experiment 3: ten far-apart indices per target, decoded (raw) and refined.

    Returns:
        per target: ``position``, ``z`` (count, latent), ``q_raw``/``q_refined`` (count, n)
        [rad], ``err_raw``/``err_refined`` (count,) [m], ``var_raw``/``var_refined`` (n,)
        per-joint variance of the solutions [deg^2] (population variance), ``distinct_raw``/
        ``distinct_refined``: solutions at least ``distinct_threshold`` apart.
    """
    out = []
    for t in targets:
        pos = np.asarray(t, dtype=float)
        z = far_apart_indices(ik, pos, count)
        q_raw = ik.decode('position', pos, None, z)
        q_ref, _, _ = ik.refine(q_raw, pos, None)
        rec = {'position': pos, 'z': z}
        for tag, q in (('raw', q_raw), ('refined', q_ref)):
            rec[f'q_{tag}'] = q
            rec[f'err_{tag}'] = position_errors(ik.robot, q, pos)
            rec[f'var_{tag}'] = np.var(np.degrees(q), axis=0)
            rec[f'distinct_{tag}'] = int(ik.distinct_mask(q, 'position').sum())
        out.append(rec)
    return out


# -- 4. posture indices ---------------------------------------------------------------------------

def latent_study(directory: Optional[Path]) -> Optional[List[Dict]]:
    """The latent-size study from checkpoints ``latent_<d>.pt`` (None without a directory).

    Returns:
        per checkpoint, sorted by size: ``latent_dim``, ``path``, ``step``, ``final_loss``,
        ``val_dist_mean_m`` (validation FK error of the last record) and ``history``.
    """
    if directory is None:
        return None
    rows = []
    for path in sorted(Path(directory).glob('latent_*.pt')):
        if not re.fullmatch(r'latent_\d+\.pt', path.name):
            continue
        ckpt = load_checkpoint(path)
        hist = list(ckpt.get('history', []))
        last = hist[-1] if hist else {}
        rows.append({'latent_dim': int(ckpt['model_config']['latent_dim']), 'path': str(path),
                     'step': int(ckpt.get('step', 0)), 'final_loss': last.get('loss'),
                     'val_dist_mean_m': last.get('val_dist_mean_m'), 'history': hist})
    return sorted(rows, key=lambda r: r['latent_dim'])


def element_sweep(ik: SelectiveIK, target: Sequence[float] = SWEEP_TARGET,
                  steps: int = 6) -> Dict:
    """Experiment 4: vary one index element at a time over its range near the target.

    The other elements stay at the median of the table's indices near the target; each element
    takes ``steps`` evenly spaced values between the minimum and maximum of those indices.

    Returns:
        ``position``, ``median`` (latent,), and per element a dict with ``values`` (steps,),
        ``q_raw``/``q_refined`` (steps, n) [rad] and ``err_raw``/``err_refined`` (steps,) [m].
    """
    pos = np.asarray(target, dtype=float)
    pool = ik.models['position'].table.candidates(pos, ik.config.k_cells).astype(np.float64)
    median = np.median(pool, axis=0)
    elements = []
    for d in range(pool.shape[1]):
        values = np.linspace(pool[:, d].min(), pool[:, d].max(), steps)
        z = np.repeat(median[None], steps, axis=0)
        z[:, d] = values
        q_raw = ik.decode('position', pos, None, z)
        q_ref, _, _ = ik.refine(q_raw, pos, None)
        elements.append({'values': values, 'q_raw': q_raw, 'q_refined': q_ref,
                         'err_raw': position_errors(ik.robot, q_raw, pos),
                         'err_refined': position_errors(ik.robot, q_ref, pos)})
    return {'position': pos, 'median': median, 'pool_size': len(pool), 'elements': elements}


# -- 5. orientation -------------------------------------------------------------------------------

def orientation_study(ik: SelectiveIK, targets: int = 4, postures: int = 5,
                      seed: int = 5, min_height: float = 0.1) -> Dict:
    """Experiment 5: pose goals (position and orientation held) with the pose model.

    Targets are reachable poses: FK of seeded uniform joint samples, the first ``targets`` whose
    tip is higher than ``min_height`` [m] above the base (above the table). Per target, the indices
    are the 0, 25, 50, 75 and 100 % quantiles (``postures`` of them) of the table's indices near
    the target's position (for a 1-d index, evenly spread along its range).

    Returns:
        ``targets`` (list of dicts: ``position``, ``quaternion``, ``z``, ``q_raw``/``q_refined``,
        ``err_raw``/``err_refined`` [m], ``cos_raw``/``cos_refined``, ``angle_raw``/
        ``angle_refined`` [rad]) and the means over every posture of every target.
    """
    rng = np.random.default_rng(seed)
    q_goal = rng.uniform(ik.robot.lower, ik.robot.upper, (50 * targets, ik.robot.dof))
    pos_all, rot_all = ik.robot.fk_rot(q_goal)
    above = np.flatnonzero(pos_all[:, 2] > min_height)[:targets]
    pos_all, rot_all = pos_all[above], rot_all[above]
    out = []
    for pos, rot in zip(pos_all, rot_all):
        pool = ik.models['pose'].table.candidates(pos, ik.config.k_cells).astype(np.float64)
        z = np.quantile(pool, np.linspace(0, 1, postures), axis=0)
        q_raw = ik.decode('pose', pos, rot, z)
        q_ref, _, _ = ik.refine(q_raw, pos, rot)
        rec = {'position': pos, 'quaternion': Rotation.from_matrix(rot).as_quat(), 'z': z}
        for tag, q in (('raw', q_raw), ('refined', q_ref)):
            p, r = ik.robot.fk_rot(q)
            cos, angle = orientation_cosine(rot, r)
            rec.update({f'q_{tag}': q, f'err_{tag}': np.linalg.norm(p - pos, axis=1),
                        f'cos_{tag}': cos, f'angle_{tag}': angle})
        out.append(rec)
    summary = {}
    for tag in ('raw', 'refined'):
        for key in ('err', 'cos', 'angle'):
            summary[f'{key}_{tag}'] = float(np.mean([t[f'{key}_{tag}'] for t in out]))
    return {'targets': out, **summary}


# -- 6. obstacle avoidance ------------------------------------------------------------------------

#: Goals tried in turn for the obstacle case [m].
OBSTACLE_GOALS = ((0.6, 0.0, 0.1), (0.5, -0.3, 0.15), (0.5, 0.3, 0.15), (0.65, 0.1, 0.3),
                  (0.45, 0.0, 0.05))


def place_box(checker, q: np.ndarray, goal: np.ndarray,
              heights: Sequence[float] = (0.15, 0.2, 0.25, 0.3, 0.4),
              size: Tuple[float, float] = (0.1, 0.3)) -> Optional[Obstacle]:
    """A box standing on the table (z = 0) between the base and the goal that a posture hits.

    The box (``size``: depth along the base-goal line, width across it [m]) is turned to face
    the line and slid along it from near the goal towards the base, for the lowest height first;
    the first place where the posture ``q`` hits it while the goal stays at least 5 cm outside
    it is returned (None if there is none).
    """
    reach = float(np.linalg.norm(goal[:2]))
    if reach < 0.35:
        return None
    u = goal[:2] / reach
    yaw = float(np.arctan2(u[1], u[0]))
    quat = (0.0, 0.0, float(np.sin(yaw / 2)), float(np.cos(yaw / 2)))
    for h in heights:
        for d in np.arange(reach - size[0] / 2 - 0.06, 0.25, -0.02):
            centre = (float(d * u[0]), float(d * u[1]), h / 2)
            box = Obstacle('box', (size[0], size[1], h), centre, quat)
            local = np.abs(_rotate_z(goal - np.array(centre), -yaw)) - np.array(box.dimensions) / 2
            if np.linalg.norm(np.maximum(local, 0)) < 0.05:
                continue
            if checker.clearance(q[None], [box])[0] <= 0:
                return box
    return None


def _rotate_z(v: np.ndarray, angle: float) -> np.ndarray:
    """A vector (3,) turned about z by ``angle`` [rad]."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]])


def obstacle_study(ik: SelectiveIK, goals: Sequence = OBSTACLE_GOALS,
                   num_solutions: int = 16) -> Dict:
    """Experiment 6: a box the first unconstrained solution hits; Algorithm 2's answer.

    For the first goal where a box can be placed (:func:`place_box`) so that the first-ranked
    unconstrained solution collides with it, solve again with the box as an obstacle: the solver
    ranks collision-free exact solutions first and runs the index adjustment (Algorithm 2) when
    none of its decoded candidates is free.

    Returns:
        ``goal``, ``box`` (:class:`Obstacle`), ``q_first`` and its ``clearance_first`` [m],
        ``q_chosen``, ``clearance_chosen`` [m], ``error_chosen`` [m], ``converged``,
        ``from_adjustment`` (the chosen posture is none of the unconstrained solutions),
        ``unconstrained_colliding`` (how many of those hit the box), ``elapsed_s``; or
        ``{'goal': None, 'reason': ...}`` when no goal gave a usable box.
    """
    for g in goals:
        goal = np.asarray(g, dtype=float)
        free = ik.solve(goal, num_solutions=ik.config.max_solutions_cap)
        if not free.solutions:
            continue
        first = free.solutions[0]
        box = place_box(ik.checker, first.q, goal)
        if box is None:
            continue
        clear_all = ik.checker.clearance(np.array([s.q for s in free.solutions]), [box])
        if clear_all[0] > 0:
            continue
        res = ik.solve(goal, num_solutions=num_solutions, obstacles=[box])
        chosen = res.solutions[0]
        seen = any(np.allclose(chosen.q, s.q, atol=1e-6) for s in free.solutions)
        return {'goal': goal, 'box': box, 'q_first': first.q,
                'clearance_first': float(clear_all[0]), 'q_chosen': chosen.q,
                'clearance_chosen': float(chosen.min_obstacle_distance),
                'error_chosen': float(position_errors(ik.robot, chosen.q, goal)[0]),
                'converged': bool(chosen.converged), 'from_adjustment': not seen,
                'unconstrained_total': len(free.solutions),
                'unconstrained_colliding': int(np.sum(clear_all <= 0)),
                'elapsed_s': float(res.elapsed)}
    return {'goal': None, 'reason': 'no goal gave a box that the first solution hits while '
            'leaving the goal free'}
