"""The paper's accuracy experiments as functions returning typed results (no printing).

Sections of the paper's "Experiments" and the function for each:

1. distance error over the workspace and per radius: :func:`workspace_targets`,
   :func:`sphere_targets`, :func:`distance_error_study`;
2. computing time: :mod:`sik_ros.eval.timing`;
3. diversity of ten far-apart postures per target: :func:`diversity_study`;
4. posture indices: :func:`element_sweep`, and the latent-size study (a training study) in
   :mod:`sik_ros.eval.histories`;
5. orientation as goal: :func:`orientation_study`;
6. obstacle avoidance with Algorithm 2: :mod:`sik_ros.eval.obstacle`.

Every distance error is recomputed from the joint angles by forward kinematics [m].
"""

from dataclasses import dataclass
from typing import Dict, List, Sequence, Tuple

import numpy as np

from sik_ros.eval.baselines import Baseline, Method
from sik_ros.eval.lookup import position_lookup, Progress
from sik_ros.eval.metrics import mean_cm, position_errors
from sik_ros.eval.paper import DIVERSITY_TARGETS, RADII, SWEEP_TARGET
from sik_ros.kinematics.robot import Robot
from sik_ros.solver import SelectiveIK
from sik_ros.solver.codec import decode
from sik_ros.solver.context import Goal, POSITION
from sik_ros.solver.ranking import posture_mask
from sik_ros.solver.refine import refine
from sik_ros.tables.index_table import PostureTable
from sik_ros.tables.point_sets import farthest_point_subset

#: Per-target distance errors [m] by variant (``lookup``, ``raw_first``, ``refined``, ...).
Errors = Dict[str, np.ndarray]


def table_pool(table: PostureTable, position: np.ndarray, k_cells: int) -> np.ndarray:
    """The posture indices a table holds near a position [m], (M, latent)."""
    return table.indices[table.rows_near(np.asarray(position, dtype=float), k_cells)]


# -- 1. distance error ----------------------------------------------------------------------------

@dataclass
class SphereTargets:
    """Reachable targets near one sphere around the base origin.

    Attributes:
        positions: (k, 3) targets [m].
        q: (k, n) joint angles reaching them [rad].
        available: how many sampled tips lay near the sphere (k is at most the number asked).
    """

    positions: np.ndarray
    q: np.ndarray
    available: int


@dataclass
class DistanceErrors:
    """Experiment 1: per-target distance errors [m] of every model.

    Attributes:
        workspace: ``{model: {variant: (N,)}}`` over the workspace targets.
        radius: ``{model: {variant: [(k,) per radius]}}`` over the sphere targets.
    """

    workspace: Dict[str, Errors]
    radius: Dict[str, Dict[str, List[np.ndarray]]]

    def radius_means_cm(self) -> Dict[str, Dict[str, List[float]]]:
        """Mean error [cm] per radius: ``{model: {variant: [per radius]}}``."""
        return {name: {v: [mean_cm(e) for e in per] for v, per in variants.items()}
                for name, variants in self.radius.items()}


def workspace_targets(robot: Robot, count: int, seed: int = 0) -> Tuple[np.ndarray, np.ndarray]:
    """Targets uniform over the workspace: FK of joint angles uniform within the limits.

    Returns:
        positions (count, 3) [m] and the configurations (count, n) [rad] that reach them.
    """
    rng = np.random.default_rng(seed)
    q = rng.uniform(robot.lower, robot.upper, (count, robot.dof))
    return robot.fk_rot(q)[0], q


def sphere_targets(robot: Robot, radii: Sequence[float] = RADII, per_radius: int = 100,
                   samples: int = 1_000_000, tol: float = 0.01, seed: int = 1,
                   chunk: int = 200_000) -> Dict[float, SphereTargets]:
    """Reachable targets near spheres around the base origin.

    Of ``samples`` uniform joint draws, the tips within ``tol`` [m] of a radius [m] from the
    base origin; ``per_radius`` of them at random (all when fewer exist).

    Returns:
        ``{radius: SphereTargets}``.
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
        out[float(r)] = SphereTargets(pos[pick], qs[pick], int(len(rows)))
    return out


def sik_errors(ik: SelectiveIK, targets: np.ndarray, progress: Progress = None,
               num_raw: int = 10) -> Errors:
    """Distance errors [m] of a SelectiveIK (SIK or PSIK) on position targets (N, 3) [m].

    Returns:
        per target: ``lookup`` (the paper's protocol: the mean over every index the table's
        look-up gives, :func:`~sik_ros.eval.lookup.position_lookup`) and ``lookup_count`` (how
        many); the product's answers: ``raw_first`` (first-ranked solution of
        ``solve(refine=False)``, the best by FK error), ``raw_mean`` (mean over its up to
        ``num_raw`` solutions), ``raw_count`` (how many it returned), ``refined`` (first-ranked
        solution of ``solve(refine=True)``).
    """
    look = position_lookup(ik, targets)
    out = {'lookup': look.distance, 'lookup_count': look.count.astype(float)}
    for key in ('raw_first', 'raw_mean', 'raw_count', 'refined'):
        out[key] = np.empty(len(targets))
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


def model_errors(model: Method, targets: np.ndarray, progress: Progress = None) -> Errors:
    """Per-target errors of a SelectiveIK (see :func:`sik_errors`) or a baseline (``raw``)."""
    if isinstance(model, SelectiveIK):
        return sik_errors(model, targets, progress)
    errs = {'raw': baseline_errors(model, targets)}
    if progress:
        progress(len(targets))
    return errs


def distance_error_study(ik: SelectiveIK, baselines: Dict[str, Method], workspace: np.ndarray,
                         spheres: Dict[float, SphereTargets],
                         progress: Progress = None) -> DistanceErrors:
    """Experiment 1: distance errors over the workspace and per radius, every model.

    Args:
        ik: the SIK solver (position goals).
        baselines: ``{name: SelectiveIK or Baseline}`` (:func:`~.baselines.load_baselines`).
        workspace: targets uniform over the workspace (N, 3) [m].
        spheres: output of :func:`sphere_targets`; ``progress``: called per target solved.
    """
    models = {'sik': ik, **baselines}
    out = DistanceErrors({}, {})
    for name, model in models.items():
        out.workspace[name] = model_errors(model, workspace, progress)
        per: Dict[str, List[np.ndarray]] = {}
        for r in spheres:
            for variant, e in model_errors(model, spheres[r].positions, progress).items():
                per.setdefault(variant, []).append(e)
        out.radius[name] = per
    return out


# -- 3. diversity ---------------------------------------------------------------------------------

@dataclass
class DiversityTarget:
    """Experiment 3 at one target: far-apart indices decoded (raw) and refined.

    Attributes:
        position: the target (3,) [m].
        z: the posture indices (count, latent).
        q_raw, q_refined: the solutions (count, n) [rad].
        err_raw, err_refined: their distance errors (count,) [m].
        var_raw, var_refined: per-joint population variance of the solutions (n,) [deg^2].
        distinct_raw, distinct_refined: how many solutions are distinct postures.
    """

    position: np.ndarray
    z: np.ndarray
    q_raw: np.ndarray
    q_refined: np.ndarray
    err_raw: np.ndarray
    err_refined: np.ndarray
    var_raw: np.ndarray
    var_refined: np.ndarray
    distinct_raw: int
    distinct_refined: int


def far_apart_indices(ik: SelectiveIK, position: np.ndarray, count: int,
                      goal: str = 'position') -> np.ndarray:
    """``count`` far-apart posture indices from the table cells near a position [m]."""
    pool = table_pool(ik.models[goal].table, position, ik.config.k_cells)
    return pool[farthest_point_subset(pool, count)]


def diversity_study(ik: SelectiveIK, targets: Sequence = DIVERSITY_TARGETS,
                    count: int = 10) -> List[DiversityTarget]:
    """Experiment 3: ten far-apart indices per target [m], decoded (raw) and refined."""
    out = []
    for t in targets:
        pos = np.asarray(t, dtype=float)
        z = far_apart_indices(ik, pos, count)
        q_raw = decode(ik.context, Goal(pos), z)
        q_ref = refine(ik.context, q_raw, Goal(pos)).q
        out.append(DiversityTarget(
            pos, z, q_raw, q_ref, position_errors(ik.robot, q_raw, pos),
            position_errors(ik.robot, q_ref, pos), np.var(np.degrees(q_raw), axis=0),
            np.var(np.degrees(q_ref), axis=0),
            int(posture_mask(ik.context, q_raw, POSITION).sum()),
            int(posture_mask(ik.context, q_ref, POSITION).sum())))
    return out


# -- 4. posture indices ---------------------------------------------------------------------------

@dataclass
class SweepElement:
    """One index element varied over its range.

    Attributes:
        values: the element's values (steps,).
        q_raw, q_refined: the solutions (steps, n) [rad].
        err_raw, err_refined: their distance errors (steps,) [m].
    """

    values: np.ndarray
    q_raw: np.ndarray
    q_refined: np.ndarray
    err_raw: np.ndarray
    err_refined: np.ndarray


@dataclass
class Sweep:
    """Experiment 4's element sweep at one target.

    Attributes:
        position: the target (3,) [m].
        median: the index the elements vary around (latent,).
        pool_size: how many table indices near the target the range comes from.
        elements: one :class:`SweepElement` per index element.
    """

    position: np.ndarray
    median: np.ndarray
    pool_size: int
    elements: List[SweepElement]


def element_sweep(ik: SelectiveIK, target: Sequence[float] = SWEEP_TARGET,
                  steps: int = 6) -> Sweep:
    """Experiment 4: vary one index element at a time over its range near the target [m].

    The other elements stay at the median of the table's indices near the target; each element
    takes ``steps`` evenly spaced values between the minimum and maximum of those indices.
    """
    pos = np.asarray(target, dtype=float)
    pool = table_pool(ik.models['position'].table, pos, ik.config.k_cells).astype(np.float64)
    median = np.median(pool, axis=0)
    elements = []
    for d in range(pool.shape[1]):
        values = np.linspace(pool[:, d].min(), pool[:, d].max(), steps)
        z = np.repeat(median[None], steps, axis=0)
        z[:, d] = values
        q_raw = decode(ik.context, Goal(pos), z)
        q_ref = refine(ik.context, q_raw, Goal(pos)).q
        elements.append(SweepElement(values, q_raw, q_ref, position_errors(ik.robot, q_raw, pos),
                                     position_errors(ik.robot, q_ref, pos)))
    return Sweep(pos, median, len(pool), elements)
