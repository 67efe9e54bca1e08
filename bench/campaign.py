"""Training campaigns' curves: validation against samples seen, from the runs' checkpoints.

Each run's ``last.pt`` holds its validation history (``sik-train --eval-every``); this prints,
per run, the validation distance (decoded from each row's own index: the decoder's floor) and,
for pose models, the orientation, against steps, samples seen and hours of training, and draws
them in one figure (a second panel for the orientation). With ``--target`` (and
``--target-deg`` for pose models' orientation) it fits the last third of the points' error
against log(samples) (a straight line, the shape the curves take once past their warm-up; a
third smooths the validation's noise) and says how many more samples and hours that line
needs to reach the target: an extrapolation, printed as such.

Usage: ``python bench/campaign.py NAME=RUN_DIR [NAME=RUN_DIR ...] [--target CM]
[--target-deg DEG] [--figure PNG] [--json PATH]``. Nothing is asserted.
"""

import argparse
import math
from pathlib import Path
import sys
from typing import Dict, List, Optional

import numpy as np

from report import add_json_argument, write_json  # noqa: I100 (bench/report.py)

#: The share of a curve's points, its last ones, that the extrapolation fits (at least 4).
TAIL_SHARE = 1 / 3


def history(run: Path) -> Dict:
    """A run's validation history and batch size, from its ``last.pt``."""
    import torch
    ckpt = torch.load(run / 'last.pt', map_location='cpu', weights_only=False)
    batch = int(ckpt['train_config']['batch_size'])
    rows = [h for h in ckpt['history'] if 'val_dist_mean_m' in h]
    return dict(batch=batch, init=ckpt['train_config'].get('init'),
                fk_weight=ckpt['train_config'].get('fk_weight'),
                rows=[dict(step=h['step'], samples=h['step'] * batch,
                           hours=h['elapsed_s'] / 3600.0,
                           dist_cm=100.0 * h['val_dist_mean_m'],
                           rot_deg=h.get('val_orient_mean_deg'))
                      for h in rows])


def extrapolate(rows: List[Dict], target: float, key: str = 'dist_cm') -> Optional[Dict]:
    """Samples and hours a straight line in log(samples) through the tail needs, or None.

    ``key``: ``dist_cm`` or ``rot_deg`` (the target in its unit).
    """
    rows = [r for r in rows if r.get(key) is not None]
    tail = rows[-max(4, int(len(rows) * TAIL_SHARE)):]
    if len(tail) < 3:
        return None
    x = np.log([r['samples'] for r in tail])
    y = np.array([r[key] for r in tail])
    slope, cut = np.polyfit(x, y, 1)
    if slope >= 0:
        return dict(slope_per_e=float(slope), points=len(tail), reached=False)
    samples = math.exp((target - cut) / slope)
    rate = tail[-1]['samples'] / max(tail[-1]['hours'], 1e-9)  # samples per hour so far
    return dict(slope_per_e=float(slope), points=len(tail), reached=True, samples=samples,
                hours=samples / rate, hours_more=max(samples - tail[-1]['samples'], 0) / rate)


def say(ex: Optional[Dict], target: float, unit: str) -> None:
    """Print an extrapolation."""
    if ex and ex['reached']:
        print(f'extrapolated (a line in log(samples) through the last {ex["points"]} points): '
              f'{target} {unit} at {ex["samples"] / 1e6:,.0f} M samples, '
              f'{ex["hours_more"]:,.1f} more hours at this rate')
    elif ex:
        print(f'the last {ex["points"]} points do not fall: no extrapolation to {target} {unit}')


def panel(ax, runs: Dict, colours: Dict, key: str, ylabel: str,
          target: Optional[float]) -> None:
    """One panel of the figure: each run's ``key`` against samples seen, and the target."""
    for name, run in runs.items():
        ax.plot([r['samples'] / 1e6 for r in run['rows']], [r[key] for r in run['rows']],
                marker='.', label=name, color=colours[name])
    if target is not None:
        ax.axhline(target, color='grey', linestyle='--', label='target')
    ax.set_xlabel('samples seen in this run [M]')
    ax.set_ylabel(ylabel)
    ax.set_xscale('log')
    ax.grid(True, alpha=0.3)
    ax.legend()


def main(argv=None) -> int:
    """Print each run's curve and, with ``--target``, its extrapolation; draw the figure."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('runs', nargs='+', help='NAME=RUN_DIR (a sik-train --out folder)')
    parser.add_argument('--target', type=float, help='validation distance to reach [cm]')
    parser.add_argument('--target-deg', type=float,
                        help='validation orientation to reach, pose models [deg]')
    parser.add_argument('--figure', help='write the curves to this PNG')
    add_json_argument(parser)
    args = parser.parse_args(argv)
    out = {}
    for spec in args.runs:
        name, _, folder = spec.partition('=')
        if not (Path(folder) / 'last.pt').is_file():
            print(f'campaign: no last.pt in {folder}', file=sys.stderr)
            return 2
        run = history(Path(folder))
        if args.target is not None:
            run['extrapolation'] = extrapolate(run['rows'], args.target)
        if args.target_deg is not None and run['rows'] and run['rows'][-1]['rot_deg']:
            run['extrapolation_deg'] = extrapolate(run['rows'], args.target_deg, 'rot_deg')
        out[name] = run
        print(f'\n{name} (batch {run["batch"]}, FK weight {run["fk_weight"]}, from '
              f'{run["init"] or "scratch"})\n')
        print('| step | samples | hours | validation distance | orientation |')
        print('|---|---|---|---|---|')
        for r in run['rows']:
            rot = '' if r['rot_deg'] is None else f'{r["rot_deg"]:.1f}°'
            print(f'| {r["step"]:,} | {r["samples"] / 1e6:.1f} M | {r["hours"]:.2f} | '
                  f'{r["dist_cm"]:.2f} cm | {rot} |')
        print()
        say(run.get('extrapolation'), args.target, 'cm')
        say(run.get('extrapolation_deg'), args.target_deg, 'deg')
    if args.figure:
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
        posed = {n: r for n, r in out.items() if r['rows'] and r['rows'][-1]['rot_deg']}
        fig, axes = plt.subplots(1, 2 if posed else 1, figsize=(12 if posed else 7, 4),
                                 squeeze=False)
        colours = {name: f'C{i}' for i, name in enumerate(out)}  # a run's colour in both
        panel(axes[0, 0], out, colours, 'dist_cm', 'validation distance, own index [cm]',
              args.target)
        if posed:
            panel(axes[0, 1], posed, colours, 'rot_deg',
                  'validation orientation, own index [deg]', args.target_deg)
        fig.tight_layout()
        fig.savefig(args.figure, dpi=110)
        print(f'\nwrote {args.figure}')
    write_json(args.json, 'campaign', out)
    return 0


if __name__ == '__main__':
    sys.exit(main())
