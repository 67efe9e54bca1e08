"""``sik-train``: train a SIK, PSIK, FCN or ANFIS model on a dataset, resumably.

With ``--chain`` (a chain file, ``sik-chain``) instead of ``--dataset`` it needs torch and NumPy
alone: the rows are generated on the training device (the Algorithm 1 grid or uniform samples)
and nothing loads Pinocchio, so it runs on a GPU machine that has neither the URDF nor
Pinocchio.
"""

import argparse
from dataclasses import replace
import json
from pathlib import Path
import sys
import time
from typing import List, Optional

from sik_ros.cli import argv_or_default, Parser, run_cli
from sik_ros.defaults import DEFAULT_LATENT, PRESETS
from sik_ros.errors import ArtifactExists, InvalidArgument


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of sik-train."""
    p = Parser(prog='sik-train', description='Train an IK model on a dataset '
               'written by sik-collect, or on rows generated on the training device from a '
               'chain file (sik-chain); checkpoints go to --out/last.pt.')
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument('--dataset', help='dataset directory (sik-collect --out)')
    src.add_argument('--chain', help='chain file (sik-chain --out): generate the rows on '
                     '--device instead (torch and NumPy only, no Pinocchio)')
    p.add_argument('--data', choices=('grid', 'uniform'), default='grid',
                   help='with --chain: the Algorithm 1 grid (default) or uniform samples')
    p.add_argument('--interval', type=float, default=30.0,
                   help='with --chain --data grid: the grid step [deg] (default: 30)')
    p.add_argument('--samples', type=int, default=1_000_000,
                   help='with --chain --data uniform: rows (default: 1,000,000)')
    p.add_argument('--out', required=True, help='run directory for checkpoints and history')
    p.add_argument('--model', choices=('sik', 'psik', 'fcn', 'anfis'), default='sik')
    p.add_argument('--goal', choices=('position', 'pose'), default='position')
    p.add_argument('--latent-dim', type=int, help='posture index size (default: 4 position, '
                   '1 pose)')
    p.add_argument('--branches', action='store_true',
                   help='a branch code beside the learned index (SIK): the signs that tell '
                   'the arm\'s shoulder and wrist flips apart (pose goals: the separate '
                   'pieces of the self-motion)')
    p.add_argument('--preset', choices=sorted(PRESETS), default='default',
                   help='layer widths (paper: the paper\'s sizes)')
    p.add_argument('--steps', type=int, help='optimiser steps (PSO iterations for ANFIS)')
    p.add_argument('--batch-size', type=int)
    p.add_argument('--lr', type=float)
    p.add_argument('--fk-weight', type=float, help='FK consistency weight (0: paper\'s loss)')
    p.add_argument('--fk-start', type=int, help='step from which the FK term is on')
    p.add_argument('--rot-weight', type=float,
                   help='weight of the orientation part of the FK term (pose goals)')
    p.add_argument('--kl-weight', type=float, help='KL weight (PSIK)')
    p.add_argument('--kl-anneal', type=int, help='PSIK: steps over which the KL weight rises '
                   'linearly from 0 to --kl-weight (default: 0, the full weight at once)')
    p.add_argument('--sampler', choices=('dataset', 'uniform'),
                   help='batches from the dataset rows (default) or drawn afresh every step '
                   '(uniform joint angles, torch FK)')
    p.add_argument('--cycle-weight', type=float,
                   help='cycle term: another index decoded at each goal must re-encode to it '
                   'and reach the goal (keeps an FK-trained decoder from ignoring the index)')
    p.add_argument('--cycle-turn', type=float,
                   help='pose goals: the cycle term also turns the goal orientation by about '
                   'this angle [rad]')
    p.add_argument('--anchor-joint', type=int,
                   help='SIK: draw the first index element towards this joint (0-based; the '
                   'Panda\'s last joint: 6), so a pose model\'s small index starts as a '
                   'coordinate of the self-motion')
    p.add_argument('--anchor-weight', type=float, help='weight of that pull (default: 1)')
    p.add_argument('--anchor-steps', type=int,
                   help='steps over which the pull falls linearly to zero (0: always on)')
    p.add_argument('--init', help='start from the weights of this checkpoint or model file '
                   '(same model config, robot and dataset normaliser; or a smaller index, '
                   'a position model for a pose model, a larger index (the new one learned '
                   'afresh, the rest kept), or a SIK model for its PSIK)')
    p.add_argument('--uni-position', action='store_true',
                   help='one row per distinct position (the paper\'s uni-position dataset)')
    p.add_argument('--eval-every', type=int)
    p.add_argument('--checkpoint-every', type=int)
    p.add_argument('--seed', type=int)
    p.add_argument('--threads', type=int)
    p.add_argument('--device', choices=('cpu', 'cuda'))
    p.add_argument('--bf16', action='store_true', default=None,
                   help='bfloat16 autocast for forward and backward (faster on CPUs with '
                   'bfloat16 units; weights stay float32)')
    p.add_argument('--max-time', type=float, help='stop cleanly after this many seconds')
    p.add_argument('--fit-schedule', action='store_true',
                   help='a new run: size the schedule (--steps, the warm-up, validations and '
                   'checkpoints) to --max-time from a step timed here first')
    p.add_argument('--resume', action='store_true', help='continue from --out/last.pt')
    p.add_argument('--export', help='also write the inference model (no optimiser) here')
    p.add_argument('--quiet', action='store_true', help='no progress bar')
    return p


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of sik-train."""
    args = build_parser().parse_args(argv_or_default(argv))
    # Ctrl-C, kill -INT and SIGTERM stop a run with a checkpoint of its last step
    # (run_cli turns both signals into a KeyboardInterrupt)
    return run_cli('sik-train', lambda: train(args),
                   'checkpoint of the last step saved (--resume continues the run)')


def train(args: argparse.Namespace) -> int:
    """One run: its configs, the trainer with a progress bar, the history and a summary line."""
    from tqdm import tqdm

    from sik_ros.artifacts import write_text_atomic
    from sik_ros.learning import distributed
    from sik_ros.learning.checkpoints import export_model, load_checkpoint, model_signature
    from sik_ros.learning.training import Trainer
    rank, size = distributed.init(args.device or 'cpu')
    out = Path(args.out)
    ckpt, model_cfg, train_cfg = run_configs(args, out)
    robot, model_cfg = for_robot(args, model_cfg)
    t0 = time.perf_counter()
    ds = training_rows(args, robot, ckpt, train_cfg)
    if args.chain and rank == 0:
        print(f'sik-train: {len(ds):,} rows ({ds.manifest["sampler"]}) generated on '
              f'{train_cfg.device} in {time.perf_counter() - t0:.1f} s', file=sys.stderr)
    if args.fit_schedule and ckpt is None:
        train_cfg = fitted_schedule(robot, ds, model_cfg, train_cfg, args, out)
    trainer = Trainer(robot, ds, model_cfg, train_cfg, out)
    if ckpt is not None:
        trainer.restore(ckpt)
    elif args.init:
        trainer.initialise(load_checkpoint(Path(args.init)), args.init)
    bar = tqdm(total=train_cfg.steps, initial=trainer.step, disable=args.quiet or rank > 0,
               desc=f'train {model_cfg.kind}/{model_cfg.goal}', mininterval=2.0)

    def progress(step, rec):
        bar.update(step - bar.n)
        if 'val_dist_mean_m' in rec:
            bar.set_postfix(loss=f"{rec['loss']:.4g}",
                            val_cm=f"{rec['val_dist_mean_m'] * 100:.2f}")
    last = trainer.run(max_time=args.max_time, progress=progress)
    bar.close()
    if rank == 0:
        write_text_atomic(out / 'history.json', json.dumps(trainer.history, indent=1))
        if args.export:
            export_model(trainer.checkpoint(), Path(args.export))
    weights = model_signature(trainer.checkpoint())['weights_sha256']
    distributed.finish()
    # one write of the whole line: ranks sharing a pipe (torchrun) never interleave it
    sys.stdout.write(json.dumps({
        'step': trainer.step, 'elapsed_s': round(trainer.elapsed, 1),
        **{k: v for k, v in last.items() if k.startswith('val')},
        'rank': rank, 'world_size': size, 'weights_sha256': weights}) + '\n')
    sys.stdout.flush()
    return 0


def fitted_schedule(robot, ds, model_cfg, train_cfg, args: argparse.Namespace, out: Path):
    """The training config with its schedule sized to ``--max-time``.

    One step (a swarm step for ANFIS) is timed on a throw-away trainer of the same model and
    rows; the schedule is 92 % of the steps that fit (validations and checkpoints take the
    rest), its warm-up at most a tenth of it, and unless given, 40 validations and 10
    checkpoints along it.
    """
    from sik_ros.learning.train_config import with_overrides
    from sik_ros.learning.training import Trainer
    probe = Trainer(robot, ds, model_cfg, with_overrides(train_cfg, steps=100),
                    out / 'probe')
    per_step = probe.seconds_per_step()
    del probe
    steps = max(1, int(0.92 * args.max_time / per_step))
    print(f'sik-train: a step takes {1e3 * per_step:.1f} ms here: {steps:,} steps in '
          f'{args.max_time:g} s', file=sys.stderr)
    return with_overrides(
        train_cfg, steps=steps, warmup=min(train_cfg.warmup, max(1, steps // 10)),
        eval_every=args.eval_every or max(1, steps // 40),
        checkpoint_every=args.checkpoint_every or max(1, steps // 10))


def run_configs(args: argparse.Namespace, out: Path):
    """The checkpoint resumed (or None), the model config and the training config of a run.

    Raises:
        InvalidArgument: contradicting or bad options.
        ArtifactExists: a new run where one already is.
    """
    from sik_ros.learning.checkpoints import load_checkpoint
    from sik_ros.learning.models import ModelConfig
    from sik_ros.learning.train_config import TrainConfig, with_overrides
    if args.max_time is not None and args.max_time <= 0:
        raise InvalidArgument(f'--max-time must be positive; got {args.max_time}')
    if args.fit_schedule and args.max_time is None:
        raise InvalidArgument('--fit-schedule sizes the schedule to --max-time: give it')
    if args.resume and args.init:
        raise InvalidArgument('--init starts a new run; --resume continues one: give one')
    if args.resume:
        ckpt = load_checkpoint(out / 'last.pt')
        train_cfg = TrainConfig(**ckpt['train_config'])
        # a resumed run may extend its schedule or switch the FK term on later
        train_cfg = with_overrides(train_cfg, steps=args.steps, fk_weight=args.fk_weight,
                                   fk_start=args.fk_start, rot_weight=args.rot_weight,
                                   cycle_weight=args.cycle_weight, cycle_turn=args.cycle_turn)
        return ckpt, ModelConfig.from_dict(ckpt['model_config']), train_cfg
    if (out / 'last.pt').exists():
        raise ArtifactExists(f'{out}/last.pt exists: use --resume, or another --out')
    enc, dec = PRESETS[args.preset]
    model_cfg = ModelConfig(kind=args.model, goal=args.goal,
                            latent_dim=args.latent_dim or DEFAULT_LATENT[args.goal],
                            encoder=enc, decoder=dec)
    train_cfg = with_overrides(
        TrainConfig(), steps=args.steps, batch_size=args.batch_size, lr=args.lr,
        fk_weight=args.fk_weight, fk_start=args.fk_start, kl_weight=args.kl_weight,
        kl_anneal=args.kl_anneal, rot_weight=args.rot_weight,
        eval_every=args.eval_every, checkpoint_every=args.checkpoint_every,
        seed=args.seed, threads=args.threads, device=args.device,
        uni_position=args.uni_position or None, bf16=args.bf16,
        sampler=args.sampler, cycle_weight=args.cycle_weight,
        cycle_turn=args.cycle_turn, init=args.init, anchor_joint=args.anchor_joint,
        anchor_weight=args.anchor_weight if args.anchor_weight is not None else (
            1.0 if args.anchor_joint is not None else None),
        anchor_steps=args.anchor_steps)
    if args.anchor_joint is not None and not (args.model == 'sik'
                                              and 0 <= args.anchor_joint):
        raise InvalidArgument('--anchor-joint needs --model sik and a joint index from 0')
    if args.model in ('fcn', 'anfis') and args.fk_weight is None:
        train_cfg = with_overrides(train_cfg, fk_weight=0.0)
    return None, model_cfg, train_cfg


def training_rows(args: argparse.Namespace, robot, ckpt, train_cfg):
    """The rows to train on: the dataset, or rows generated on the device from the chain.

    A resumed run on generated rows makes those it started with (its checkpoint's sampler and
    parameters; ``--data``, ``--interval`` and ``--samples`` are then not read).
    """
    if args.dataset:
        from sik_ros.tables.dataset import Dataset
        return Dataset.load(args.dataset, robot)
    from sik_ros.learning.generated_data import GeneratedData
    spec = {'sampler': args.data, 'interval_deg': args.interval, 'samples': args.samples,
            'seed': train_cfg.seed}
    if ckpt is not None:
        before = ckpt.get('dataset', {})
        if before.get('kind') != 'generated':
            raise InvalidArgument('--resume --chain: the run trained on a dataset '
                                  '(give --dataset)')
        spec = {'sampler': before['sampler'], 'interval_deg': 30.0, 'samples': 0, 'seed': 0,
                **before['params']}
    return GeneratedData(robot, spec['sampler'], float(spec['interval_deg']),
                         int(spec['samples']), int(spec['seed']), train_cfg.device)


def for_robot(args: argparse.Namespace, model_cfg):
    """The robot (the dataset's, or the chain file's arm) and the model config fitted to it."""
    from sik_ros.learning.models import branch_bits, ModelConfig
    if args.chain:
        from sik_ros.kinematics.chain_file import load_chain_file
        robot = load_chain_file(Path(args.chain))
    else:
        from sik_ros.kinematics.robots import robot_from_manifest
        from sik_ros.tables.dataset import Dataset
        robot = robot_from_manifest(Dataset.load(args.dataset).manifest['robot'],
                                    f'dataset {args.dataset}')
    if model_cfg.dof != robot.dof:
        model_cfg = ModelConfig(**{**model_cfg.__dict__, 'dof': robot.dof})
    if args.branches and not args.resume:
        if args.model != 'sik':
            raise InvalidArgument('--branches needs --model sik')
        model_cfg = replace(model_cfg, branches=branch_bits(robot.chain, robot.lower,
                                                            robot.upper))
    return robot, model_cfg


if __name__ == '__main__':
    raise SystemExit(main())
