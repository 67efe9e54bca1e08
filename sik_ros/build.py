"""From an arm to a served bundle in one resumable job: collect, train, index, bundle, check.

Stages, each recorded in ``<work>/state.json`` once done, so a rerun (after Ctrl-C, a crash or a
reboot) continues where it stopped:

1. **collect**: the uniform sampler (or the Algorithm 1 grid at the finest interval under the row
   budget) over the arm's joint space;
2. **train**: the position model, then the pose model started from it (its posture index of
   the whole self-motion; the orientation inputs at zero weight) and fine-tuned with the FK
   term, the orientation weighed up and the cycle term (docs/training.md); one after the other,
   each on the cores the build may use, for its share of the budget (:data:`TRAIN_SHARES`);
   each checkpoints as it goes and resumes from its ``last.pt``;
3. **index**: each model's posture-index table over the dataset;
4. **bundle**: models and tables in a bundle directory, renamed onto ``--out`` only when
   complete (an interrupted build leaves nothing that looks finished);
5. **self-check**: random reachable targets solved per goal kind; success, distinct solutions
   and time per call, printed and stored in ``bundle.json``.

The work directory (``<out>.build`` by default) holds the dataset and the runs; delete it once
the bundle is built.
"""

from dataclasses import asdict, replace
import json
import multiprocessing
import os
from pathlib import Path
import time
from typing import Callable, Dict, Optional

import numpy as np

from sik_ros.artifacts import atomic_directory, read_json, write_json_atomic
from sik_ros.bundle import build_bundle, read_bundle_manifest
from sik_ros.dataset import collect, Dataset, finest_interval, MAX_ROWS
from sik_ros.defaults import BuildConfig  # noqa: F401 (part of this module's API)
from sik_ros.errors import ArtifactMismatch, InvalidArgument
from sik_ros.kinematics import Robot
from sik_ros.models import ModelConfig, PRESETS
from sik_ros.robots import robot_from_manifest
from sik_ros.train_config import TrainConfig

GOALS = ('position', 'pose')
#: The training time's split, in order: the position model first, then the pose model started
#: from it (measured on the xArm7: docs/training.md, "Your own arm").
TRAIN_SHARES = {'position': 0.5, 'pose': 0.5}
#: The pose model's fine-tune from the position model (the bundled Panda pose model's recipe):
#: a lower peak learning rate (a warm start), the FK term on from the first step with the
#: orientation weighed x4, the cycle term turning the goal orientation by about 0.25 rad.
POSE_RECIPE = {'lr': 3e-4, 'fk_weight': 0.05, 'fk_start': 0, 'rot_weight': 4.0,
               'cycle_weight': 0.1, 'cycle_turn': 0.25}
#: Torch threads of each training (one after the other): the two cores two parallel trainings
#: would take, fewer on a one-core machine.
TRAIN_THREADS = 2
Say = Callable[[str], None]


def latent_dims(robot: Robot) -> Dict[str, int]:
    """Posture index sizes per goal kind: the arm's redundancy for a position (1 to 4).

    The pose model keeps the position model's index (it starts from that model): the index of
    the position's whole self-motion, of which a pose's self-motion is a part.
    """
    size = max(1, min(4, robot.dof - 3))
    return {'position': size, 'pose': size}


def train_threads() -> int:
    """Torch threads of a build's training: :data:`TRAIN_THREADS`, at most the cores here."""
    return max(1, min(TRAIN_THREADS, len(os.sched_getaffinity(0))))


def _train_worker(robot_manifest: Dict, dataset: str, goal: str, run: str, cfg: Dict,
                  seconds: float, init: Optional[str] = None) -> None:
    """One model's training (in its own process): resume or start, run for ``seconds``, export.

    A new run starts from the weights of ``init`` (a model file) when given.
    """
    from sik_ros.checkpoints import export_model, load_checkpoint
    from sik_ros.models import ModelConfig
    from sik_ros.training import TrainConfig, Trainer
    robot = robot_from_manifest(robot_manifest, 'build')
    ds = Dataset.load(dataset, robot)
    model_cfg = ModelConfig.from_dict(cfg['model'])
    trainer = Trainer(robot, ds, model_cfg, TrainConfig(**cfg['train']), Path(run))
    if (Path(run) / 'last.pt').exists():
        trainer.restore(load_checkpoint(Path(run) / 'last.pt'))
    elif init:
        trainer.initialise(load_checkpoint(Path(init)), f'the {Path(init).parent.name} model')
    try:
        trainer.run(max_time=max(1.0, seconds - trainer.elapsed))
    except KeyboardInterrupt:
        trainer.save()
        return
    export_model(trainer.checkpoint(), Path(run) / 'model.pt')


class Builder:
    """One build: its robot, settings, work directory and output bundle."""

    def __init__(self, robot: Robot, out: Path, cfg: BuildConfig,
                 work: Optional[Path] = None, say: Say = print, bars: bool = True):
        self.robot, self.out, self.cfg = robot, Path(out), cfg
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

    # -- stages ----------------------------------------------------------------------------

    def run(self) -> Dict:
        """Every stage not yet done; the self-check's figures."""
        t0 = time.perf_counter()
        state = self._state()
        # the self-check and the solver rank by collision geometry: a missing mesh fails here,
        # not after the training
        self.robot.collision_model
        if (self.out / 'bundle.json').exists() and 'bundle' not in state['done']:
            raise InvalidArgument(f'{self.out} already holds a bundle (remove it or use '
                                  f'another --out)')
        self.work.mkdir(parents=True, exist_ok=True)
        write_json_atomic(self.state_file, state)
        if 'collect' not in state['done']:
            self._done(state, 'collect', self.collect())
        if 'train' not in state['done']:
            spent = time.perf_counter() - t0
            self._done(state, 'train', self.train(self.train_seconds(spent)))
        if 'bundle' not in state['done']:
            self._done(state, 'bundle', self.bundle())
        check = state['done'].get('check') or self.self_check()
        self._done(state, 'check', check)
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

    def model_configs(self) -> Dict[str, ModelConfig]:
        """The two models' configs: the pose model is the position model with pose goals."""
        enc, dec = PRESETS[self.cfg.preset]
        position = ModelConfig(kind='sik', goal='position', dof=self.robot.dof,
                               latent_dim=latent_dims(self.robot)['position'], encoder=enc,
                               decoder=dec)
        return {'position': position, 'pose': replace(position, goal='pose')}

    def train_config(self, goal: str, steps: int, rows: int) -> TrainConfig:
        """One model's training config, its schedule ``steps`` long, for a dataset of ``rows``."""
        recipe = POSE_RECIPE if goal == 'pose' else {
            'fk_weight': 0.005, 'fk_start': int(0.55 * steps)}
        init = 'run_position/model.pt' if goal == 'pose' else ''
        return TrainConfig(steps=steps, batch_size=self.cfg.batch_size,
                           warmup=min(500, steps // 10), val_rows=min(20_000, rows // 10),
                           eval_every=max(10, steps // 20), checkpoint_every=max(10, steps // 20),
                           seed=self.cfg.seed, device=self.cfg.device, threads=train_threads(),
                           init=init, **recipe)

    def train_configs(self, seconds: float) -> Dict[str, Dict]:
        """Model and training configs per goal kind, each schedule sized to its share of time.

        Each model gets its :data:`TRAIN_SHARES` of ``seconds`` [s]. The time of a step is
        measured here, for each model with its own recipe (the pose
        model's cycle term makes its steps dearer), on the threads the training will use.
        """
        from sik_ros.training import Trainer
        import torch
        ds = Dataset.load(self.work / 'dataset', self.robot)
        rows = len(ds)
        out = {}
        for goal, model in self.model_configs().items():
            probe = replace(self.train_config(goal, 100, rows), val_rows=min(1000, rows // 10))
            threads = torch.get_num_threads()
            try:
                per_step = Trainer(self.robot, ds, model, probe,
                                   self.work / 'probe').seconds_per_step()
            finally:
                torch.set_num_threads(threads)
            share = TRAIN_SHARES[goal] * seconds
            steps = max(50, int(0.95 * share / per_step))
            train = self.train_config(goal, steps, rows)
            out[goal] = {'model': asdict(model), 'train': asdict(train), 'seconds': share}
            self.say(f'{goal} model: {steps:,} steps of {self.cfg.batch_size} at '
                     f'{1e3 * per_step:.0f} ms each (measured) in {share:.0f} s, index of '
                     f'{model.latent_dim}'
                     + (', started from the position model' if train.init else ''))
        return out

    def train(self, seconds: float) -> Dict:
        """Stage 2: the position model, then the pose model from it, each for its share."""
        plan_file = self.work / 'train_plan.json'
        if plan_file.exists():  # a resumed build keeps its schedule
            plan = read_json(plan_file, 'training plan')
        else:
            plan = {'seconds': seconds, 'shares': TRAIN_SHARES,
                    'configs': self.train_configs(seconds)}
            write_json_atomic(plan_file, plan)
        info = {}
        for goal in GOALS:
            model_file = self.work / f'run_{goal}' / 'model.pt'
            if not model_file.exists():
                self._train_one(goal, plan['configs'][goal])
            hist = json.loads(json.dumps(_history(model_file)))
            info[goal] = {**hist, 'seconds': plan['configs'][goal]['seconds'],
                          'init': plan['configs'][goal]['train']['init']}
            self.say(f'trained {goal} model: {hist["step"]} steps, validation error '
                     f'{100 * hist.get("val_dist_mean_m", float("nan")):.2f} cm'
                     + (f' / {hist["val_orient_mean_deg"]:.1f} deg'
                        if 'val_orient_mean_deg' in hist else ''))
        return info

    def _train_one(self, goal: str, plan: Dict) -> None:
        """One model's training in its own process, for its planned seconds.

        Raises:
            InvalidArgument: the training stopped without its model file.
        """
        from tqdm import tqdm
        run = self.work / f'run_{goal}'
        run.mkdir(parents=True, exist_ok=True)
        init = str(self.work / plan['train']['init']) if plan['train']['init'] else None
        ctx = multiprocessing.get_context('spawn')
        p = ctx.Process(target=_train_worker, name=f'sik_train_{goal}',
                        args=(self.robot.manifest(), str(self.work / 'dataset'), goal,
                              str(run), plan, plan['seconds'], init))
        p.start()
        t0 = time.perf_counter()
        with tqdm(total=round(plan['seconds']), desc=f'train {goal}', unit='s',
                  disable=not self.bars) as bar:
            try:
                while p.is_alive():
                    time.sleep(1.0)
                    bar.update(min(round(time.perf_counter() - t0), bar.total) - bar.n)
            except KeyboardInterrupt:
                p.join(30)
                raise
        if p.exitcode != 0 or not (run / 'model.pt').exists():
            raise InvalidArgument(f'training of the {goal} model stopped early; rerun to '
                                  f'continue from the checkpoints in {self.work}')

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
            manifest['training'] = self.training_summary()
            write_json_atomic(tmp / 'bundle.json', manifest)
        size = sum(f.stat().st_size for f in self.out.iterdir())
        self.say(f'bundle {self.out}: {size / 1e6:.1f} MB')
        return {'bytes': size}

    def training_summary(self) -> Dict:
        """Per model: its share of the training time [s], steps planned and done, its start.

        ``init`` names the model a model started from (``position``), or is empty (from
        scratch); it goes into ``bundle.json`` as ``training``.
        """
        plan = read_json(self.work / 'train_plan.json', 'training plan')
        out = {}
        for goal in GOALS:
            cfg = plan['configs'][goal]
            hist = _history(self.work / f'run_{goal}' / 'model.pt')
            init = cfg['train']['init']
            out[goal] = {'seconds': round(cfg['seconds'], 1),
                         'share': plan.get('shares', {}).get(goal),
                         'steps_planned': cfg['train']['steps'], 'steps': hist['step'],
                         'init': Path(init).parent.name.replace('run_', '') if init else ''}
        return out

    def self_check(self) -> Dict:
        """Stage 5: random reachable targets per goal kind, the figures stored in the bundle."""
        from sik_ros.solver import SelectiveIK
        ik = SelectiveIK.load(self.out)
        rng = np.random.default_rng(self.cfg.seed + 1)
        q = rng.uniform(self.robot.lower, self.robot.upper,
                        (self.cfg.check_targets, self.robot.dof))
        report = {}
        for goal in GOALS:
            ok, distinct, times = 0, [], []
            for qi in q:
                p, quat = ik.fk(qi)
                t0 = time.perf_counter()
                res = ik.solve(p, quat if goal == 'pose' else None, num_solutions=16)
                times.append(time.perf_counter() - t0)
                ok += res.success
                distinct.append(sum(s.converged for s in res.solutions))
            report[goal] = {'targets': len(q), 'success': ok / len(q),
                            'distinct_median': float(np.median(distinct)),
                            'distinct_p10': float(np.percentile(distinct, 10)),
                            'time_median_ms': 1e3 * float(np.median(times))}
            r = report[goal]
            self.say(f'self-check, {goal} goals: success {100 * r["success"]:.1f} % of '
                     f'{len(q)}, distinct exact solutions median {r["distinct_median"]:.0f} '
                     f'(p10 {r["distinct_p10"]:.0f}) of 16, {r["time_median_ms"]:.1f} ms per '
                     f'call')
        manifest = read_bundle_manifest(self.out)
        manifest['self_check'] = report
        write_json_atomic(self.out / 'bundle.json', manifest)
        return report


def _history(model_file: Path) -> Dict:
    """Steps, time and the last validation figures of an exported model."""
    from sik_ros.checkpoints import load_checkpoint
    ckpt = load_checkpoint(model_file)
    last = ckpt.get('history', [{}])[-1] if ckpt.get('history') else {}
    return {'step': int(ckpt.get('step', 0)), 'elapsed_s': float(ckpt.get('elapsed_s', 0.0)),
            **{k: float(v) for k, v in last.items() if k.startswith('val')}}
