"""From an arm to a served bundle in one resumable job: collect, train, index, bundle, check.

Stages, each recorded in ``<work>/state.json`` once done, so a rerun (after Ctrl-C, a crash or a
reboot) continues where it stopped:

1. **collect**: the uniform sampler (or the Algorithm 1 grid at the finest interval under the row
   budget) over the arm's joint space;
2. **train**: the position model on one core for the training time; the pose model on the
   other, started part way from the position model's checkpoint and fine-tuned with the pose
   recipe (:mod:`sik_ros.bundles.build_training`); each checkpoints as it goes and resumes from its
   ``last.pt``;
3. **index**: each model's posture-index table over the dataset;
4. **bundle**: models and tables in a bundle directory, renamed onto ``--out`` only when
   complete (an interrupted build leaves nothing that looks finished);
5. **self-check**: the caller's check of the bundle (``sik-build``'s: random reachable targets
   solved per goal kind; success, distinct solutions and time per call), printed and stored in
   ``bundle.json``. The solver is a layer below the bundles it loads: the check is handed in
   (:class:`Check`), this module does not import it.

The work directory (``<out>.build`` by default) holds the dataset and the runs; delete it once
the bundle is built. It also holds ``progress.json`` (the stage, the share of the whole build done
and the time left, rewritten as the build goes), which a node building its arm in the background
shows on ``/diagnostics``. A finished bundle gets ``checksums.json`` last
(:func:`~sik_ros.bundles.cache.write_checksums`) and its chain's cache key in ``bundle.json``, so
that it can be copied into a node's cache (:mod:`sik_ros.bundles.cache`).
"""

from dataclasses import asdict
import os
from pathlib import Path
import time
from typing import Callable, Dict, Optional

from sik_ros.artifacts import atomic_directory, read_json, write_json_atomic
from sik_ros.bundles.build_training import (GOALS, history, latent_dims,  # noqa: F401 (API)
                                            plan_training, run_training, Say, training_summary)
from sik_ros.bundles.bundle import build_bundle, read_bundle_manifest
from sik_ros.bundles.cache import CHECKSUMS, write_checksums
from sik_ros.defaults import BuildConfig  # noqa: F401 (part of this module's API)
from sik_ros.errors import ArtifactMismatch, InvalidArgument
from sik_ros.kinematics.arm_description import chain_key
from sik_ros.kinematics.robot import Robot
from sik_ros.tables.dataset import collect, Dataset, finest_interval, MAX_ROWS


#: The self-check stage: (the bundle, its robot, the build's settings, the reporter) -> the
#: figures stored in ``bundle.json`` under ``self_check``.
Check = Callable[[Path, Robot, BuildConfig, Say], Dict]
#: Each stage's share of a build's time, for the progress it reports (train: the rest).
STAGE_SHARES = {'collect': 0.05, 'index': 0.08, 'check': 0.04}


class Builder:
    """One build: its robot, settings, work directory, output bundle and self-check."""

    def __init__(self, robot: Robot, out: Path, cfg: BuildConfig, check: Check,
                 work: Optional[Path] = None, say: Say = print, bars: bool = True):
        self.robot, self.out, self.cfg, self.check = robot, Path(out), cfg, check
        self.work = Path(work) if work else self.out.with_name(self.out.name + '.build')
        self.say, self.bars = say, bars
        self.state_file = self.work / 'state.json'

    # -- state -----------------------------------------------------------------------------

    def _state(self) -> Dict:
        if not self.state_file.exists():
            return {'robot': self.robot.manifest(), 'config': asdict(self.cfg), 'done': {}}
        state = read_json(self.state_file, f'build state {self.state_file}')
        if state.get('robot') != self.robot.manifest():
            raise ArtifactMismatch(f'{self.work}: the build was started for another robot',
                                   state.get('robot'), self.robot.manifest())
        old = {k: v for k, v in state.get('config', {}).items() if k != 'time'}
        new = {k: v for k, v in asdict(self.cfg).items() if k != 'time'}
        if old != new:
            raise ArtifactMismatch(f'{self.work}: the build was started with other settings '
                                   f'(delete the folder to start again)', old, new)
        return state

    def _done(self, state: Dict, stage: str, info: Dict) -> None:
        state['done'][stage] = info
        self.work.mkdir(parents=True, exist_ok=True)
        write_json_atomic(self.state_file, state)

    def report(self, stage: str, within: float = 0.0) -> None:
        """Write ``progress.json``: the stage, the whole build's share done, the time left [s].

        ``within``: the share of ``stage`` done [0-1].
        """
        order = ('collect', 'train', 'index', 'check', 'done')
        train = 1.0 - sum(STAGE_SHARES.values())
        shares = dict(STAGE_SHARES, train=train, done=0.0)
        done = sum(shares[s] for s in order[:order.index(stage)]) + shares[stage] * within
        done = min(max(done, 0.0), 1.0)
        left = 0.0 if stage == 'done' else max(self.cfg.time * (1.0 - done), 0.0)
        write_json_atomic(self.work / 'progress.json', {
            'stage': stage, 'percent': round(100.0 * done, 1), 'seconds_left': round(left),
            'time': time.time(), 'pid': os.getpid()})

    # -- stages ----------------------------------------------------------------------------

    def run(self) -> Dict:
        """Every stage not yet done; the self-check's figures."""
        t0 = time.perf_counter()
        state = self._state()
        if self.cfg.device == 'cuda':
            import torch
            if not torch.cuda.is_available():
                raise InvalidArgument('--device cuda: torch sees no CUDA device here')
        # the self-check and the solver rank by collision geometry: a missing mesh fails here,
        # not after the training
        self.robot.collision_model
        if (self.out / 'bundle.json').exists() and 'bundle' not in state['done']:
            raise InvalidArgument(f'{self.out} already holds a bundle (remove it or use '
                                  f'another --out)')
        self.work.mkdir(parents=True, exist_ok=True)
        write_json_atomic(self.state_file, state)
        if 'collect' not in state['done']:
            self.report('collect')
            self._done(state, 'collect', self.collect())
        if 'train' not in state['done']:
            spent = time.perf_counter() - t0
            self.report('train')
            self._done(state, 'train', self.train(self.train_seconds(spent)))
        if 'bundle' not in state['done']:
            self.report('index')
            self._done(state, 'bundle', self.bundle())
        self.report('check')
        check = state['done'].get('check') or self.self_check()
        self._done(state, 'check', check)
        if not (self.out / CHECKSUMS).is_file():
            write_checksums(self.out)
        self.report('done', 1.0)
        self.say(f'bundle {self.out} ready in {time.perf_counter() - t0:.0f} s '
                 f'(work files in {self.work})')
        return check

    def collect(self) -> Dict:
        """Stage 1: the dataset."""
        from tqdm import tqdm
        cfg, robot = self.cfg, self.robot
        interval, samples = 30.0, cfg.rows
        if cfg.sampler == 'grid':
            interval = finest_interval(robot, cfg.rows)
            if interval is None:
                raise InvalidArgument(f'no grid fits {cfg.rows:,} rows: use the uniform sampler')
        with tqdm(desc='collect', unit='rows', unit_scale=True, disable=not self.bars) as bar:
            ds = collect(robot, self.work / 'dataset', cfg.sampler, interval, samples,
                         cfg.seed, force=True, progress=bar.update, max_rows=MAX_ROWS)
        self.say(f'collected {len(ds):,} rows ({cfg.sampler}'
                 f'{f" at {interval:g} deg" if cfg.sampler == "grid" else ""})')
        return {'rows': len(ds)}

    def train_seconds(self, spent: float) -> float:
        """The training's share of the budget: what the other stages (estimated) leave."""
        rows = read_json(self.work / 'dataset' / 'manifest.json', 'dataset')['count']
        rest = 10.0 + 4 * rows / 100_000 + self.cfg.check_targets * 0.1
        seconds = self.cfg.time - spent - rest
        if seconds < 5:
            raise InvalidArgument(f'--time {self.cfg.time:g} s leaves no time to train (the '
                                  f'other stages need about {spent + rest:.0f} s)')
        return seconds

    def train(self, seconds: float) -> Dict:
        """Stage 2: the position and the pose model (:mod:`sik_ros.bundles.build_training`)."""
        plan_file = self.work / 'train_plan.json'
        if plan_file.exists():  # a resumed build keeps its schedule
            plan = read_json(plan_file, 'training plan')
        else:
            plan = plan_training(self.robot, self.cfg, self.work, seconds, self.say)
            write_json_atomic(plan_file, plan)
        run_training(self.robot, self.work, plan, self.bars,
                     lambda trained: self.report('train', trained / max(plan['seconds'], 1.0)))
        info = training_summary(self.work, plan)
        for goal in GOALS:
            hist = history(self.work / f'run_{goal}' / 'model.pt')
            info[goal].update(hist)
            self.say(f'trained {goal} model: {hist["step"]} steps, validation error '
                     f'{100 * hist.get("val_dist_mean_m", float("nan")):.2f} cm'
                     + (f' / {hist["val_orient_mean_deg"]:.1f} deg'
                        if 'val_orient_mean_deg' in hist else ''))
        return info

    def self_check(self) -> Dict:
        """Stage 5: the caller's check of the bundle, its figures stored in the bundle."""
        report = self.check(self.out, self.robot, self.cfg, self.say)
        manifest = read_bundle_manifest(self.out)
        manifest['self_check'] = report
        write_json_atomic(self.out / 'bundle.json', manifest)
        return report

    def bundle(self) -> Dict:
        """Stages 3 and 4: the tables and the bundle, renamed onto ``out`` when complete."""
        from tqdm import tqdm
        ds = Dataset.load(self.work / 'dataset', self.robot)
        models = {g: self.work / f'run_{g}' / 'model.pt' for g in GOALS}
        with atomic_directory(self.out, force=self.out.exists()) as tmp:
            with tqdm(total=len(ds) * len(GOALS), desc='index', unit='rows', unit_scale=True,
                      disable=not self.bars) as bar:
                build_bundle(tmp, self.robot, models, ds, progress=bar.update)
            manifest = read_bundle_manifest(tmp)
            manifest['training'] = training_summary(
                self.work, read_json(self.work / 'train_plan.json', 'training plan'))
            manifest['chain_key'] = chain_key(self.robot)
            write_json_atomic(tmp / 'bundle.json', manifest)
        size = sum(f.stat().st_size for f in self.out.iterdir())
        self.say(f'bundle {self.out}: {size / 1e6:.1f} MB')
        return {'bytes': size}
