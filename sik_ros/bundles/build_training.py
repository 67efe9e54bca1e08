"""The training stage of ``sik-build``: its plan, and the position and pose models' runs.

The position model trains for the whole training time on one core. The pose model starts on
the other core once :data:`POSE_START` of that time has passed, from the position model's
checkpoint of that moment (its posture index of the whole self-motion; the orientation inputs
at zero weight, :func:`sik_ros.learning.warm_start.widened_state`), and is fine-tuned for the
rest of the time with the FK term, the orientation weighed up and the cycle term
(:data:`POSE_RECIPE`, the bundled Panda pose model's recipe; docs/training.md). Each run has
one thread: on a shared machine two threads of one run are slower than one (a step waits for
the slower thread). Each checkpoints as it goes and resumes from its ``last.pt``.
"""

from dataclasses import asdict, replace
import multiprocessing
import os
from pathlib import Path
import shutil
import time
from typing import Callable, Dict, Optional

from sik_ros.defaults import BuildConfig
from sik_ros.errors import InvalidArgument, SikError
from sik_ros.kinematics.robot import Robot
from sik_ros.kinematics.robots import robot_from_manifest
from sik_ros.learning.models import ModelConfig, PRESETS
from sik_ros.learning.train_config import TrainConfig
from sik_ros.tables.dataset import Dataset

GOALS = ('position', 'pose')
#: When the pose model starts, as a share of the training time [0-1): from the position
#: model's checkpoint of that moment, for the rest of the time.
POSE_START = 0.5
#: The pose model's fine-tune (the bundled Panda pose model's recipe): a lower peak learning
#: rate (a warm start), the FK term on from the first step with the orientation weighed x4,
#: the cycle term turning the goal orientation by about 0.25 rad.
POSE_RECIPE = {'lr': 3e-4, 'fk_weight': 0.05, 'fk_start': 0, 'rot_weight': 4.0,
               'cycle_weight': 0.1, 'cycle_turn': 0.25}
#: The position model's checkpoint the pose model starts from (in the work directory).
POSE_INIT = 'run_pose/start.pt'
Say = Callable[[str], None]


def latent_dims(robot: Robot) -> Dict[str, int]:
    """Posture index sizes per goal kind: the arm's redundancy for a position (1 to 4).

    The pose model keeps the position model's index (it starts from that model): the index of
    the position's whole self-motion, of which a pose's self-motion is a part.
    """
    size = max(1, min(4, robot.dof - 3))
    return {'position': size, 'pose': size}


def model_configs(robot: Robot, preset: str) -> Dict[str, ModelConfig]:
    """The two models' configs: the pose model is the position model with pose goals."""
    enc, dec = PRESETS[preset]
    position = ModelConfig(kind='sik', goal='position', dof=robot.dof,
                           latent_dim=latent_dims(robot)['position'], encoder=enc, decoder=dec)
    return {'position': position, 'pose': replace(position, goal='pose')}


def train_config(cfg: BuildConfig, goal: str, steps: int, rows: int) -> TrainConfig:
    """One model's training config, its schedule ``steps`` long, for a dataset of ``rows``.

    On a GPU (``cfg.device`` ``cuda``) every batch is drawn afresh on the device (``uniform``:
    joint values uniform within the limits, their tips by the torch FK), as ``sik-train
    --chain`` trains there; the dataset gives the normaliser and the validation rows.
    """
    recipe = POSE_RECIPE if goal == 'pose' else {'fk_weight': 0.005,
                                                 'fk_start': int(0.55 * steps)}
    sampler = 'uniform' if cfg.device == 'cuda' else 'dataset'
    return TrainConfig(steps=steps, batch_size=cfg.batch_size, warmup=min(500, steps // 10),
                       sampler=sampler,
                       val_rows=min(20_000, rows // 10), eval_every=max(10, steps // 20),
                       checkpoint_every=max(10, steps // 20), seed=cfg.seed, device=cfg.device,
                       init=POSE_INIT if goal == 'pose' else '', **recipe)


def plan_training(robot: Robot, cfg: BuildConfig, work: Path, seconds: float,
                  say: Say = print) -> Dict:
    """Each model's configs and time, its schedule sized to a step's time measured here.

    Args:
        robot: the arm.
        cfg: the build's settings.
        work: the work directory (its ``dataset``).
        seconds: the training time [s].
        say: where the plan is told.

    Returns:
        ``seconds``, ``pose_start`` [s after the position model's start] and per goal kind the
        model and training configs and its ``seconds``.
    """
    from sik_ros.learning.training import Trainer
    ds = Dataset.load(work / 'dataset', robot)
    rows = len(ds)
    plan = {'seconds': seconds, 'pose_start': POSE_START * seconds, 'configs': {},
            'cores': cfg.cores}
    for goal, model in model_configs(robot, cfg.preset).items():
        probe = replace(train_config(cfg, goal, 100, rows), val_rows=min(1000, rows // 10))
        per_step = Trainer(robot, ds, model, probe, work / 'probe').seconds_per_step()
        share = seconds - (plan['pose_start'] if goal == 'pose' else 0.0)
        if goal == 'position' and cfg.cores == 1:  # one after the other
            share = plan['pose_start']
        steps = max(50, int(0.95 * share / per_step))
        train = train_config(cfg, goal, steps, rows)
        plan['configs'][goal] = {'model': asdict(model), 'train': asdict(train),
                                 'seconds': share}
        say(f'{goal} model: {steps:,} steps of {cfg.batch_size} at {1e3 * per_step:.0f} ms '
            f'each (measured) in {share:.0f} s, index of {model.latent_dim}'
            + (f', from the position model after {plan["pose_start"]:.0f} s'
               if goal == 'pose' else ''))
    return plan


def train_worker(robot_manifest: Dict, dataset: str, run: str, cfg: Dict,
                 init: Optional[str] = None) -> None:
    """One model's training (in its own process): resume or start, run its time, export.

    A new run starts from the weights of ``init`` (a checkpoint or model file) when given.
    """
    from sik_ros.learning.checkpoints import export_model, load_checkpoint
    from sik_ros.learning.training import Trainer
    robot = robot_from_manifest(robot_manifest, 'build')
    ds = Dataset.load(dataset, robot)
    trainer = Trainer(robot, ds, ModelConfig.from_dict(cfg['model']),
                      TrainConfig(**cfg['train']), Path(run))
    if (Path(run) / 'last.pt').exists():
        trainer.restore(load_checkpoint(Path(run) / 'last.pt'))
    elif init:
        trainer.initialise(load_checkpoint(Path(init)), 'the position model')
    try:
        trainer.run(max_time=max(1.0, cfg['seconds'] - trainer.elapsed))
    except KeyboardInterrupt:
        trainer.save()
        return
    export_model(trainer.checkpoint(), Path(run) / 'model.pt')


def pose_start_snapshot(work: Path) -> bool:
    """Copy the position model's latest checkpoint to :data:`POSE_INIT`; whether there is one."""
    target = work / POSE_INIT
    if target.exists():
        return True
    run = work / 'run_position'
    source = run / 'last.pt' if (run / 'last.pt').exists() else run / 'model.pt'
    if not source.exists():
        return False
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(target.name + '.tmp')
    shutil.copyfile(source, tmp)
    os.replace(tmp, target)
    return True


def run_training(robot: Robot, work: Path, plan: Dict, bars: bool = True,
                 progress: Optional[Callable[[float], None]] = None) -> None:
    """Both models' runs: the position model's at once, the pose model's at its start.

    A resumed build starts a pose run begun before at once, else when the position model has
    trained ``pose_start`` seconds in all (or has finished); on one core (the plan's
    ``cores``), once the position model has finished. ``progress`` is called about once a
    second with the seconds trained so far (both runs' time, from their checkpoints).

    Raises:
        InvalidArgument: a run stopped without its model file.
    """
    from tqdm import tqdm
    ctx = multiprocessing.get_context('spawn')
    procs: Dict[str, multiprocessing.Process] = {}
    done = {g: (work / f'run_{g}' / 'model.pt').exists() for g in GOALS}
    pose_at = _pose_wait(work, plan) if plan.get('cores', 2) == 2 else float('inf')
    t0 = time.perf_counter()
    before = _trained_seconds(work)
    with tqdm(total=round(plan['seconds']), desc='train position+pose', unit='s',
              disable=not bars) as bar:
        try:
            while True:
                position_over = done['position'] or (
                    'position' in procs and not procs['position'].is_alive())
                if not done['position'] and 'position' not in procs:
                    procs['position'] = _start(ctx, robot, work, 'position', plan)
                if (not done['pose'] and 'pose' not in procs
                        and (time.perf_counter() - t0 >= pose_at or position_over)
                        and pose_start_snapshot(work)):
                    procs['pose'] = _start(ctx, robot, work, 'pose', plan)
                pose_over = done['pose'] or ('pose' in procs and not procs['pose'].is_alive())
                if position_over and (pose_over or 'pose' not in procs):
                    break
                time.sleep(1.0)
                bar.update(min(round(time.perf_counter() - t0), bar.total) - bar.n)
                if progress is not None:
                    progress(before + time.perf_counter() - t0)
        except KeyboardInterrupt:
            for p in procs.values():
                p.join(30)
            raise
    failed = [g for g in GOALS if not (work / f'run_{g}' / 'model.pt').exists()]
    if failed:
        raise InvalidArgument(f'training of the {failed} model(s) stopped early; rerun to '
                              f'continue from the checkpoints in {work}')


def _trained_seconds(work: Path) -> float:
    """Seconds both runs have trained so far, by their last checkpoints (0 for none)."""
    total = 0.0
    for goal in GOALS:
        last = work / f'run_{goal}' / 'last.pt'
        if last.exists():
            try:
                total += history(last)['elapsed_s']
            except (SikError, OSError):  # being replaced: counted at the next call
                pass
    return total


def _pose_wait(work: Path, plan: Dict) -> float:
    """Seconds from now until the pose model starts: what the position model has still to do."""
    last = work / 'run_position' / 'last.pt'
    if (work / 'run_pose' / 'last.pt').exists() or (work / POSE_INIT).exists():
        return 0.0
    done = history(last)['elapsed_s'] if last.exists() else 0.0
    return max(0.0, plan['pose_start'] - done)


def _start(ctx, robot: Robot, work: Path, goal: str, plan: Dict) -> multiprocessing.Process:
    """Start one model's run in its own process."""
    run = work / f'run_{goal}'
    run.mkdir(parents=True, exist_ok=True)
    cfg = plan['configs'][goal]
    init = str(work / cfg['train']['init']) if cfg['train']['init'] else None
    p = ctx.Process(target=train_worker, name=f'sik_train_{goal}',
                    args=(robot.manifest(), str(work / 'dataset'), str(run), cfg, init))
    p.start()
    return p


def history(model_file: Path) -> Dict:
    """Steps, time and the last validation figures of a checkpoint or exported model."""
    from sik_ros.learning.checkpoints import load_checkpoint
    ckpt = load_checkpoint(model_file)
    last = ckpt.get('history', [{}])[-1] if ckpt.get('history') else {}
    return {'step': int(ckpt.get('step', 0)), 'elapsed_s': float(ckpt.get('elapsed_s', 0.0)),
            **{k: float(v) for k, v in last.items() if k.startswith('val')}}


def training_summary(work: Path, plan: Dict) -> Dict:
    """Per model: its training time [s], steps planned and done, the model it started from.

    ``init`` is ``position`` for a model started from the position model (``init_step``: that
    model's step then, ``start_s``: when it started [s]) and empty for one from scratch; it
    goes into ``bundle.json`` as ``training``.
    """
    out = {}
    for goal in GOALS:
        cfg = plan['configs'][goal]
        hist = history(work / f'run_{goal}' / 'model.pt')
        out[goal] = {'seconds': round(cfg['seconds'], 1), 'steps_planned': cfg['train']['steps'],
                     'steps': hist['step'], 'init': ''}
        if cfg['train']['init']:
            out[goal].update(init='position', start_s=round(plan['pose_start'], 1),
                             init_step=history(work / cfg['train']['init'])['step'])
    return out
