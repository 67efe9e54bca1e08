"""Training recipes side by side: validation curves against training time, and solver figures.

Each run directory holds a ``last.pt`` written by ``sik-train`` (its history: validation distance
error and index spread over training time); with ``--solver``, each run's model is encoded into a
table (``sik-index``, a copy of the bundled Panda bundle) and the solver is measured on uniform
targets: the raw position error (mean of the 10 solutions of ``solve(refine=False)``, and the
first-ranked one), distinct exact solutions of 16, and the paper's Table 4 (10 far-apart indices
per target, decoded, no selection).

    python bench/recipes.py RUN_DIR ... [--solver] [--figure docs/figures/recipes.png]
"""

import argparse
import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile

os.environ.setdefault('OMP_NUM_THREADS', '1')

import numpy as np  # noqa: E402
import torch  # noqa: E402

from sik_ros.bundles.bundle import resolve_bundle  # noqa: E402
from sik_ros.eval.plots import new_figure, save_figure  # noqa: E402
from sik_ros.eval.studies import diversity_study  # noqa: E402
from sik_ros.learning.checkpoints import load_checkpoint  # noqa: E402
from sik_ros.solver import SelectiveIK  # noqa: E402

from report import add_json_argument, write_json  # noqa: E402,I100 (bench/report.py)
from solve import distinct_count  # noqa: E402 (bench/solve.py)


def solver_figures(bundle: Path, targets: int, seed: int = 123) -> dict:
    """Raw errors, distinct exact solutions and Table 4 of a bundle's position model."""
    ik = SelectiveIK.load(str(bundle))
    robot, rng = ik.robot, np.random.default_rng(seed)
    raw, first, distinct = [], [], []
    for _ in range(targets):
        p, _ = robot.fk(rng.uniform(robot.lower, robot.upper))
        r = ik.solve(p, None, num_solutions=10, refine=False)
        raw += [s.position_error for s in r.solutions]
        first.append(r.solutions[0].position_error)
        r = ik.solve(p, None, num_solutions=16)
        distinct.append(distinct_count([s.q for s in r.solutions if s.converged], True))
    table4 = np.mean([d.err_raw.mean() for d in diversity_study(ik)])
    return {'raw': np.mean(raw), 'first': np.mean(first), 'distinct': np.median(distinct),
            'distinct_p10': np.percentile(distinct, 10), 'table4': table4}


def with_table(run: Path, dataset: str, work: Path) -> Path:
    """A copy of the bundled Panda bundle whose position model and table are the run's."""
    bundle = work / run.name
    shutil.copytree(resolve_bundle('panda'), bundle)
    subprocess.run([sys.executable, '-m', 'sik_ros.cli.index', '--model', str(run / 'last.pt'),
                    '--dataset', dataset, '--out', str(work / f'{run.name}.npz'), '--force',
                    '--bundle', str(bundle), '--quiet'], check=True)
    return bundle


def main() -> None:
    """Print the recipes' table (and draw their curves)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('runs', nargs='+', help='sik-train run directories')
    parser.add_argument('--solver', action='store_true', help='also the solver figures')
    parser.add_argument('--dataset', default='data/panda30', help='dataset for the tables')
    parser.add_argument('--targets', type=int, default=200)
    parser.add_argument('--figure', help='write the validation curves here (.png)')
    add_json_argument(parser)
    args = parser.parse_args()
    torch.set_num_threads(1)
    runs = [Path(r) for r in args.runs]
    ckpts = {r: load_checkpoint(r / 'last.pt') for r in runs}
    solver_cols = (' raw mean of 10 [cm] | raw 1st [cm] | distinct of 16 (p10) '
                   '| Table 4 [cm] |') if args.solver else ''
    print('| run | sampler | FK weight | cycle | steps | samples | time [s] | val dist [cm] '
          '| index spread |' + solver_cols)
    print('|---' * (9 + 4 * args.solver) + '|')
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for r, c in ckpts.items():
            cfg, last = c['train_config'], c['history'][-1]
            line = (f"| {r.name} | {cfg.get('sampler', 'dataset')} | {cfg['fk_weight']} "
                    f"| {cfg.get('cycle_weight', 0)} | {c['step']} "
                    f"| {c['step'] * cfg['batch_size'] / 1e6:.1f} M | {c['elapsed_s']:.0f} "
                    f"| {100 * last['val_dist_mean_m']:.2f} "
                    f"| {last.get('val_index_spread', float('nan')):.2f} |")
            row = {'run': r.name, 'sampler': cfg.get('sampler', 'dataset'),
                   'fk_weight': cfg['fk_weight'], 'cycle_weight': cfg.get('cycle_weight', 0),
                   'steps': c['step'], 'samples': c['step'] * cfg['batch_size'],
                   'elapsed_s': c['elapsed_s'], 'val_dist_m': last['val_dist_mean_m'],
                   'index_spread': last.get('val_index_spread')}
            rows.append(row)
            if args.solver:
                f = solver_figures(with_table(r, args.dataset, Path(tmp)), args.targets)
                row.update(solver=f)
                line += (f" {100 * f['raw']:.3f} | {100 * f['first']:.3f} | {f['distinct']:.0f} "
                         f"({f['distinct_p10']:.0f}) | {100 * f['table4']:.2f} |")
            print(line, flush=True)
    write_json(args.json, 'recipes', {'targets': args.targets, 'runs': rows})
    if args.figure:
        fig = new_figure(7, 4)
        ax = fig.add_subplot(1, 1, 1)
        for r, c in ckpts.items():
            h = c['history']
            ax.plot([x['elapsed_s'] / 60 for x in h], [100 * x['val_dist_mean_m'] for x in h],
                    label=r.name)
        ax.set_xlabel('training time [min]')
        ax.set_ylabel('validation distance error [cm]')
        ax.legend()
        ax.grid(alpha=0.3)
        print(f'figure: {save_figure(fig, Path(args.figure))}')


if __name__ == '__main__':
    main()
