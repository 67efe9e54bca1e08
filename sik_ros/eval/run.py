"""One evaluation run: the six experiments in order, then the report's figures.

:func:`run_evaluation` returns a :class:`Results` that :mod:`sik_ros.eval.report` turns into
``results.md`` and :mod:`sik_ros.eval.summary` into ``results.json``.
"""

from dataclasses import dataclass, field
import os
from pathlib import Path
import platform
from typing import Callable, Dict, List, Optional, Protocol, Tuple, Union

import numpy as np
import torch

from sik_ros.eval import plots
from sik_ros.eval.baselines import Method, multi_solution, single_solution, TracIK
from sik_ros.eval.histories import bundle_histories, latent_study, LatentRun, TrainedModel
from sik_ros.eval.index_properties import index_properties, IndexProperties
from sik_ros.eval.lookup import LookupErrors, pose_lookup
from sik_ros.eval.obstacle import NoObstacleCase, obstacle_study, ObstacleCase
from sik_ros.eval.orientation_study import Orientation, orientation_study
from sik_ros.eval.paper import LETTERS, NAMES, PAPER, RADII, VARIANTS
from sik_ros.eval.raw_pose import raw_pose_study, RawPose, SEED, TARGETS
from sik_ros.eval.studies import (distance_error_study, DistanceErrors, diversity_study,
                                  DiversityTarget, element_sweep, sphere_targets,
                                  SphereTargets, Sweep, workspace_targets)
from sik_ros.eval.timing import Timing, timing_study
from sik_ros.solver import SelectiveIK

#: Radii of a ``--quick`` run [m].
QUICK_RADII = (0.1, 0.3, 0.5, 0.7)
#: Workspace targets at which pairs of indices are decoded with their midpoints.
INDEX_TARGETS = 50


class ProgressBar(Protocol):
    """What a run needs of a progress bar (a ``tqdm``)."""

    total: Optional[float]

    def update(self, n: float = 1) -> Optional[bool]:
        """Count ``n`` steps done."""

    def set_description(self, desc: Optional[str] = None, refresh: bool = True) -> None:
        """Name the current stage."""

    def refresh(self) -> None:
        """Redraw."""


@dataclass(frozen=True)
class Settings:
    """How much to run.

    Attributes:
        quick: a reduced run (few targets and radii).
        targets: targets per radius and over the workspace.
        samples: joint samples searched for targets near each radius.
        seed: seed of the target sampling.
        latent_dir: folder of the latent-size study's ``latent_<d>.pt`` (None: not run).
    """

    quick: bool = False
    targets: int = 100
    samples: int = 1_000_000
    seed: int = 0
    latent_dir: Optional[Union[str, Path]] = None

    @classmethod
    def of(cls, quick: bool, targets: Optional[int] = None, samples: Optional[int] = None,
           seed: int = 0, latent_dir: Optional[Union[str, Path]] = None) -> 'Settings':
        """Settings with the defaults of a full or a quick run for what is not given."""
        return cls(quick, targets or (5 if quick else 100),
                   samples or (100_000 if quick else 1_000_000), seed, latent_dir)

    @property
    def radii(self) -> Tuple[float, ...]:
        """The radii of the per-radius study [m]."""
        return QUICK_RADII if self.quick else RADII


@dataclass
class Machine:
    """Where a run ran: platform, processor, cores, library versions, load at the start."""

    platform: str
    cpu: str
    cores: Optional[int]
    torch_threads: int
    python: str
    torch: str
    load_average: List[float]


def machine_info() -> Machine:
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
    return Machine(platform.platform(), cpu, os.cpu_count(), torch.get_num_threads(),
                   platform.python_version(), str(torch.__version__),
                   [round(v, 2) for v in load])


@dataclass
class Results:
    """Everything one run measured, and the figures it drew.

    Attributes:
        settings: what was run.
        machine: where.
        workspace_targets: targets uniform over the workspace (N, 3) [m].
        spheres: targets near each radius [m].
        distance: experiment 1.
        timing: experiment 2 (see :func:`sik_ros.eval.timing.timing_study`).
        tracik_note: why TRAC-IK was not run ('' when it was).
        diversity: experiment 3, per multi-solution solver.
        latent: experiment 4's latent-size study (None: not asked for).
        sweep: experiment 4's element sweep.
        histories: the bundle's training summaries, by goal kind.
        orientation: experiment 5 (None: the bundle has no pose model).
        obstacle: experiment 6.
        raw_pose: experiment 5's raw pose answers of the product, as shipped and with
            self-collision unchecked (:mod:`~sik_ros.eval.raw_pose`; empty: no pose model).
        pose_lookup: experiment 5 by the paper's protocol (:func:`~.lookup.pose_lookup`, the
            targets of ``raw_pose``; None: no pose model).
        index_props: experiment 4's index range and interpolation, per multi-solution solver
            (:mod:`~sik_ros.eval.index_properties`).
        figures: ``{key: path relative to the report}`` of the PNG files drawn.
        date: when the run started (set by the caller).
        elapsed_s: how long it took [s] (set by the caller).
    """

    settings: Settings
    machine: Machine
    workspace_targets: np.ndarray
    spheres: Dict[float, SphereTargets]
    distance: DistanceErrors
    timing: Dict[str, Timing]
    tracik_note: str
    diversity: Dict[str, List[DiversityTarget]]
    latent: Optional[List[LatentRun]]
    sweep: Sweep
    histories: Dict[str, TrainedModel]
    orientation: Optional[Orientation]
    obstacle: Optional[Union[ObstacleCase, NoObstacleCase]]
    index_props: Dict[str, IndexProperties] = field(default_factory=dict)
    raw_pose: Dict[str, RawPose] = field(default_factory=dict)
    pose_lookup: Optional[LookupErrors] = None
    figures: Dict[str, str] = field(default_factory=dict)
    date: str = ''
    elapsed_s: float = 0.0


def run_evaluation(ik: SelectiveIK, baselines: Dict[str, Method], settings: Settings,
                   fig_dir: Path, bar: ProgressBar) -> Results:
    """All six experiments on ``ik`` and the baselines, then the figures into ``fig_dir``."""
    robot, seed = ik.robot, settings.seed
    machine = machine_info()

    def step(n: int = 1) -> None:
        bar.update(n)

    bar.set_description('sampling targets')
    ws, _ = workspace_targets(robot, settings.targets, seed=seed)
    spheres = sphere_targets(robot, settings.radii, settings.targets, settings.samples,
                             seed=seed + 1)
    solvers = multi_solution(ik, baselines)
    n_radius = sum(len(s.positions) for s in spheres.values())
    n_timing = min(settings.targets, 100)
    timed = 5 * len(solvers) + len(single_solution(baselines)) + 1
    bar.total = (1 + len(baselines)) * (len(ws) + n_radius) + n_timing * timed + 9 + len(solvers)
    bar.refresh()

    bar.set_description('1 distance error')
    distance = distance_error_study(ik, baselines, ws, spheres, step)

    bar.set_description('2 computing time')
    q_t = np.random.default_rng(seed + 2).uniform(robot.lower, robot.upper,
                                                  (n_timing, robot.dof))
    pos_t, quat_t = robot.fk_batch(q_t)
    try:
        tracik, note = TracIK(robot), ''
    except ImportError as exc:
        tracik, note = None, f'TRAC-IK not run: pytracik is not importable ({exc}).'
    timing = timing_study(ik, baselines, pos_t, quat_t, tracik, seed, step)

    bar.set_description('3 diversity')
    diversity = {name: diversity_study(s) for name, s in solvers.items()}
    step()

    bar.set_description('4 posture indices')
    latent = latent_study(settings.latent_dir)
    sweep = element_sweep(ik)
    histories = bundle_histories(ik)
    index_props = {name: index_properties(s, ws[:INDEX_TARGETS])
                   for name, s in solvers.items() if 'position' in s.goals}
    step()

    bar.set_description('5 orientation')
    orientation = orientation_study(ik) if 'pose' in ik.goals else None
    raw_pose, pose_look = {}, None
    if 'pose' in ik.goals:
        n_pose = min(settings.targets, TARGETS)
        raw_pose = raw_pose_study(ik, n_pose)
        q_pose = np.random.default_rng(SEED).uniform(robot.lower, robot.upper, (n_pose, robot.dof))
        pose_look = pose_lookup(ik, *robot.fk_rot(q_pose))
    step()

    bar.set_description('6 obstacle')
    obstacle = obstacle_study(ik) if 'position' in ik.goals else None
    step()

    res = Results(settings, machine, ws, spheres, distance, timing, note, diversity, latent,
                  sweep, histories, orientation, obstacle, index_props, raw_pose, pose_look)
    bar.set_description('figures')
    draw_figures(res, ik, baselines, fig_dir, step)
    return res


def draw_figures(res: Results, ik: SelectiveIK, baselines: Dict[str, Method], fig_dir: Path,
                 step: Callable[[int], None]) -> None:
    """Every PNG of the report into ``fig_dir``, their relative paths into ``res.figures``."""
    robot = ik.robot

    def figure(key: str, draw: Callable[[Path], Path]) -> None:
        draw(fig_dir / f'{key}.png')
        res.figures[key] = f'figures/{key}.png'

    ours = {}
    for name, variants in res.distance.radius_means_cm().items():
        for v in ('lookup', 'raw'):
            if v in variants:
                ours[f'{NAMES[name]} {VARIANTS[v]}'] = variants[v]
    paper = {NAMES[k]: v for k, v in PAPER['radius_cm'].items() if k == 'sik' or k in baselines}
    # only the paper's protocol is drawn beside the paper's figures (the product's answers
    # are selected by their error)
    figure('error_vs_radius', lambda p: plots.error_vs_radius(
        [100 * r for r in res.settings.radii], ours, paper, p,
        paper_radii_cm=[100 * r for r in RADII]))
    step()
    for name, recs in res.diversity.items():
        rows = [(LETTERS[i], r.q_raw, r.position, [f'{100 * e:.2f} cm' for e in r.err_raw])
                for i, r in enumerate(recs)]
        figure(f'diversity_{name}', lambda p, rows=rows, name=name: plots.posture_grid(
            robot, rows, p, f'{NAMES[name]}: ten far-apart posture indices per target (raw '
            'decoder output; caption: distance error)'))
        step()
    sw = res.sweep
    rows = [(f'element {d + 1}', e.q_raw, sw.position,
             [f'{v:+.2f}: {100 * err:.2f} cm' for v, err in zip(e.values, e.err_raw)])
            for d, e in enumerate(sw.elements)]
    figure('element_sweep', lambda p: plots.posture_grid(
        robot, rows, p, 'One index element varied at (-0.25, -0.25, 0.25), others at the '
        'median (raw; caption: value: error)'))
    step()
    hist = {f'SIK {goal}': h.history for goal, h in res.histories.items()}
    hist.update({f'{NAMES[k]}': b.history for k, b in single_solution(baselines).items()
                 if b.history})
    if any(hist.values()):
        figure('training_curves', lambda p: plots.training_curves(hist, p))
    if res.latent:
        figure('latent_study', lambda p: plots.training_curves(
            {f'latent {r.latent_dim}': r.history for r in res.latent}, p))
    step()
    if res.orientation is not None:
        rows = [(LETTERS[i], t.q_raw, t.position,
                 [f'{100 * e:.1f} cm, {np.degrees(a):.0f}°' for e, a in zip(t.err_raw,
                                                                            t.angle_raw)])
                for i, t in enumerate(res.orientation.targets)]
        figure('orientation', lambda p: plots.posture_grid(
            robot, rows, p, 'Pose goals, 1-d index: five postures per target (raw; caption: '
            'distance error, orientation error)'))
    step()
    ob = res.obstacle
    if isinstance(ob, ObstacleCase):
        figure('obstacle', lambda p: plots.obstacle_figure(
            robot, ob.q_first, ob.q_chosen, ob.box, ob.goal, p,
            (f'first unconstrained solution: clearance {100 * ob.clearance_first:+.1f} cm',
             f'chosen with the box: clearance {100 * ob.clearance_chosen:+.1f} cm')))
    step()
