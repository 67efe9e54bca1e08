"""Training throughput: samples/s of one training step (data, forward, backward, optimiser).

For a preset model on a uniform Panda dataset it times steps per batch size and thread count,
in float32 and with bfloat16 autocast, and with ``torch.compile`` when asked, one process,
after warm-up steps. Prints a table (samples/s, median of ``--repeats`` timings).

    python bench/train_step.py --preset default --batches 512,2048,8192 --threads 1,2 \
        --json docs/results/train_step.json
"""

import argparse
from dataclasses import replace
import os
from pathlib import Path
import tempfile

os.environ.setdefault('OMP_NUM_THREADS', '1')

import numpy as np  # noqa: E402
import torch  # noqa: E402

from sik_ros.kinematics.robots import load_robot  # noqa: E402
from sik_ros.learning.models import ModelConfig, PRESETS  # noqa: E402
from sik_ros.learning.train_config import TrainConfig  # noqa: E402
from sik_ros.learning.training import Trainer  # noqa: E402
from sik_ros.tables.dataset import collect  # noqa: E402

from report import add_json_argument, write_json  # noqa: E402,I100 (bench/report.py)


def rate(trainer: Trainer, steps: int, repeats: int, bf16: bool) -> float:
    """Samples per second of a training step, median over ``repeats`` timings."""
    trainer.cfg = replace(trainer.cfg, bf16=bf16)
    trainer.seconds_per_step(2)  # warm-up
    times = [trainer.seconds_per_step(steps) for _ in range(repeats)]
    return trainer.cfg.batch_size / float(np.median(times))


def main() -> None:
    """Time the grid of settings and print one row each."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--preset', default='default', choices=sorted(PRESETS))
    parser.add_argument('--goal', default='position', choices=('position', 'pose'))
    parser.add_argument('--batches', default='512,2048,8192')
    parser.add_argument('--threads', default='1,2')
    parser.add_argument('--steps', type=int, default=10)
    parser.add_argument('--repeats', type=int, default=3)
    parser.add_argument('--compile', action='store_true', help='also time torch.compile')
    add_json_argument(parser)
    args = parser.parse_args()
    robot = load_robot('panda')
    work = Path(tempfile.mkdtemp(prefix='sik_train_step_'))
    ds = collect(robot, work / 'ds', sampler='uniform', samples=200_000, seed=0)
    enc, dec = PRESETS[args.preset]
    model = ModelConfig(goal=args.goal, latent_dim=4 if args.goal == 'position' else 1,
                        encoder=enc, decoder=dec)
    print(f'# bench/train_step.py: {args.preset} preset ({enc} / {dec}), {args.goal} goals, '
          f'torch {torch.__version__}, {os.cpu_count()} cores')
    print('| batch | threads | float32 [samples/s] | bfloat16 autocast [samples/s] |'
          + (' compiled float32 [samples/s] | compiled bfloat16 [samples/s] |'
             if args.compile else ''))
    print('|---|---|---|---|' + ('---|---|' if args.compile else ''))
    table = []
    for batch in map(int, args.batches.split(',')):
        for threads in map(int, args.threads.split(',')):
            cfg = TrainConfig(steps=10 ** 6, batch_size=batch, threads=threads, val_rows=1000)
            trainer = Trainer(robot, ds, model, cfg, work / 'run')
            row = [rate(trainer, args.steps, args.repeats, False),
                   rate(trainer, args.steps, args.repeats, True)]
            if args.compile:
                trainer.net = torch.compile(trainer.model)
                row += [rate(trainer, args.steps, args.repeats, False),
                        rate(trainer, args.steps, args.repeats, True)]
            table.append({'batch': batch, 'threads': threads, 'float32': row[0],
                          'bfloat16': row[1], 'compiled': row[2:]})
            print(f'| {batch} | {threads} | ' + ' | '.join(f'{r:,.0f}' for r in row) + ' |',
                  flush=True)
    write_json(args.json, 'train_step', {'preset': args.preset, 'encoder': enc, 'decoder': dec,
                                         'goal': args.goal, 'rows': table})


if __name__ == '__main__':
    main()
