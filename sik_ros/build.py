"""From an arm to a served bundle in one resumable job: collect, train, index, bundle, check.

Stages, each recorded in ``<work>/state.json`` once done, so a rerun (after Ctrl-C, a crash or a
reboot) continues where it stopped:

1. **collect**: the uniform sampler (or the Algorithm 1 grid at the finest interval under the row
   budget) over the arm's joint space;
2. **train**: the position and the pose model at once, one process each (both cores), sharing
   the time budget; each checkpoints as it goes and resumes from its ``last.pt``;
3. **index**: each model's posture-index table over the dataset;
4. **bundle**: models and tables in a bundle directory, renamed onto ``--out`` only when
   complete (an interrupted build leaves nothing that looks finished);
5. **self-check**: random reachable targets solved per goal kind; success, distinct solutions
   and time per call, printed and stored in ``bundle.json``.

The work directory (``<out>.build`` by default) holds the dataset and the runs; delete it once
the bundle is built.
"""

from dataclasses import asdict
import json
import multiprocessing
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
from sik_ros.models import PRESETS
from sik_ros.robots import robot_from_manifest

GOALS = ('position', 'pose')
Say = Callable[[str], None]


def latent_dims(robot: Robot) -> Dict[str, int]:
    """Posture index sizes: the arm's redundancy per goal kind (at least 1, at most 4)."""
    return {'position': max(1, min(4, robot.dof - 3)), 'pose': max(1, min(4, robot.dof - 6))}


def _train_worker(robot_manifest: Dict, dataset: str, goal: str, run: str, cfg: Dict,
                  seconds: float) -> None:
    """One model's training (in its own process): resume, run for ``seconds``, export."""
    import torch
    from sik_ros.checkpoints import export_model, load_checkpoint
    from sik_ros.models import ModelConfig
    from sik_ros.training import TrainConfig, Trainer
    robot = robot_from_manifest(robot_manifest, 'build')
    ds = Dataset.load(dataset, robot)
    model_cfg = ModelConfig.from_dict(cfg['model'])
    trainer = Trainer(robot, ds, model_cfg, TrainConfig(**cfg['train']), Path(run))
    if (Path(run) / 'last.pt').exists():
        trainer.restore(load_checkpoint(Path(run) / 'last.pt'))
    torch.set_num_threads(1)
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

    def train_configs(self, seconds: float) -> Dict[str, Dict]:
        """Model and training configs per goal kind, the schedule sized to ``seconds``."""
        from sik_ros.training import TrainConfig
        import torch
        from sik_ros.models import branch_bits, ModelConfig
        from sik_ros.training import Trainer
        enc, dec = PRESETS[self.cfg.preset]
        ds = Dataset.load(self.work / 'dataset', self.robot)
        rows = len(ds)
        out = {}
        for goal, latent in latent_dims(self.robot).items():
            # the pose model's index: the learned part and the arm's branch code (its
            # shoulder and wrist flips), which tells the separate pieces of a pose's
            # self-motion (or a 6-joint arm's isolated branches) apart
            bits = branch_bits(self.robot.chain, self.robot.lower, self.robot.upper) \
                if goal == 'pose' else ()
            model = ModelConfig(kind='sik', goal=goal, dof=self.robot.dof, latent_dim=latent,
                                encoder=enc, decoder=dec, branches=bits)
            probe = TrainConfig(steps=100, batch_size=self.cfg.batch_size, fk_weight=0.005,
                                val_rows=min(1000, rows // 10), device=self.cfg.device)
            threads = torch.get_num_threads()
            torch.set_num_threads(1)  # as each training process will run
            try:
                per_step = Trainer(self.robot, ds, model, probe,
                                   self.work / 'probe').seconds_per_step()
            finally:
                torch.set_num_threads(threads)
            steps = max(50, int(0.95 * seconds / per_step))
            train = TrainConfig(steps=steps, batch_size=self.cfg.batch_size,
                                warmup=min(500, steps // 10), fk_weight=0.005,
                                fk_start=int(0.55 * steps), val_rows=min(20_000, rows // 10),
                                eval_every=max(10, steps // 20),
                                checkpoint_every=max(10, steps // 20), seed=self.cfg.seed,
                                device=self.cfg.device)
            out[goal] = {'model': asdict(model), 'train': asdict(train)}
            self.say(f'{goal} model: {steps:,} steps of {self.cfg.batch_size} at '
                     f'{1e3 * per_step:.0f} ms each (measured), index of {latent}'
                     + (f' and a branch code of {len(bits)} bits' if bits else ''))
        return out

    def train(self, seconds: float) -> Dict:
        """Stage 2: both models at once, each in its own process, for ``seconds``."""
        from tqdm import tqdm
        plan_file = self.work / 'train_plan.json'
        if plan_file.exists():  # a resumed build keeps its schedule
            plan = read_json(plan_file, 'training plan')
        else:
            plan = {'seconds': seconds, 'configs': self.train_configs(seconds)}
            write_json_atomic(plan_file, plan)
        ctx = multiprocessing.get_context('spawn')
        procs = []
        for goal in GOALS:
            run = self.work / f'run_{goal}'
            run.mkdir(parents=True, exist_ok=True)
            p = ctx.Process(target=_train_worker, name=f'sik_train_{goal}',
                            args=(self.robot.manifest(), str(self.work / 'dataset'), goal,
                                  str(run), plan['configs'][goal], plan['seconds']))
            p.start()
            procs.append(p)
        t0 = time.perf_counter()
        with tqdm(total=round(plan['seconds']), desc='train position+pose', unit='s',
                  disable=not self.bars) as bar:
            try:
                while any(p.is_alive() for p in procs):
                    time.sleep(1.0)
                    bar.update(min(round(time.perf_counter() - t0), bar.total) - bar.n)
            except KeyboardInterrupt:
                for p in procs:
                    p.join(30)
                raise
        failed = [g for g, p in zip(GOALS, procs) if p.exitcode != 0
                  or not (self.work / f'run_{g}' / 'model.pt').exists()]
        if failed:
            raise InvalidArgument(f'training of the {failed} model(s) stopped early; rerun to '
                                  f'continue from the checkpoints in {self.work}')
        info = {}
        for goal in GOALS:
            hist = json.loads(json.dumps(_history(self.work / f'run_{goal}' / 'model.pt')))
            info[goal] = hist
            self.say(f'trained {goal} model: {hist["step"]} steps, validation error '
                     f'{100 * hist.get("val_dist_mean_m", float("nan")):.2f} cm')
        return info

    def bundle(self) -> Dict:
        """Stages 3 and 4: the tables and the bundle, renamed onto ``out`` when complete."""
        from tqdm import tqdm
        ds = Dataset.load(self.work / 'dataset', self.robot)
        models = {g: self.work / f'run_{g}' / 'model.pt' for g in GOALS}
        with atomic_directory(self.out, force=self.out.exists()) as tmp:
            with tqdm(total=len(ds) * len(GOALS), desc='index', unit='rows', unit_scale=True,
                      disable=not self.bars) as bar:
                build_bundle(tmp, self.robot, models, ds, progress=bar.update)
        size = sum(f.stat().st_size for f in self.out.iterdir())
        self.say(f'bundle {self.out}: {size / 1e6:.1f} MB')
        return {'bytes': size}

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
