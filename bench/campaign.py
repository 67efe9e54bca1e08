"""Training campaigns' curves: validation against samples seen, from the runs' checkpoints.

Each run's ``last.pt`` holds its validation history (``sik-train --eval-every``); this prints,
per run, the validation distance (decoded from each row's own index: the decoder's floor) and,
for pose models, the orientation, against steps, samples seen and hours of training, and draws
them in one figure. With ``--target`` it fits the last points' error against log(samples)
(a straight line, the shape the curves take once past their warm-up) and says how many more
samples and hours that line needs to reach the target: an extrapolation, printed as such.

Usage: ``python bench/campaign.py NAME=RUN_DIR [NAME=RUN_DIR ...] [--target CM]
[--figure PNG] [--json PATH]``. Nothing is asserted.
"""

import argparse
import math
from pathlib import Path
import sys
from typing import Dict, List, Optional

import numpy as np

from report import add_json_argument, write_json  # noqa: I100 (bench/report.py)

#: Points of a curve's tail the extrapolation fits.
TAIL = 4


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


def extrapolate(rows: List[Dict], target_cm: float) -> Optional[Dict]:
    """Samples and hours a straight line in log(samples) through the tail needs, or None."""
    tail = rows[-TAIL:]
    if len(tail) < 3:
        return None
    x = np.log([r['samples'] for r in tail])
    y = np.array([r['dist_cm'] for r in tail])
    slope, cut = np.polyfit(x, y, 1)
    if slope >= 0:
        return dict(slope_cm_per_e=float(slope), reached=False)
    samples = math.exp((target_cm - cut) / slope)
    rate = tail[-1]['samples'] / max(tail[-1]['hours'], 1e-9)  # samples per hour so far
    return dict(slope_cm_per_e=float(slope), reached=True, samples=samples,
                hours=samples / rate, hours_more=max(samples - tail[-1]['samples'], 0) / rate)


def main(argv=None) -> int:
    """Print each run's curve and, with ``--target``, its extrapolation; draw the figure."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('runs', nargs='+', help='NAME=RUN_DIR (a sik-train --out folder)')
    parser.add_argument('--target', type=float, help='validation distance to reach [cm]')
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
        out[name] = run
        print(f'\n{name} (batch {run["batch"]}, FK weight {run["fk_weight"]}, from '
              f'{run["init"] or "scratch"})\n')
        print('| step | samples | hours | validation distance | orientation |')
        print('|---|---|---|---|---|')
        for r in run['rows']:
            rot = '' if r['rot_deg'] is None else f'{r["rot_deg"]:.1f}°'
            print(f'| {r["step"]:,} | {r["samples"] / 1e6:.1f} M | {r["hours"]:.2f} | '
                  f'{r["dist_cm"]:.2f} cm | {rot} |')
        ex = run.get('extrapolation')
        if ex and ex['reached']:
            print(f'\nextrapolated (a line in log(samples) through the last {TAIL} points): '
                  f'{args.target} cm at {ex["samples"] / 1e6:,.0f} M samples, '
                  f'{ex["hours_more"]:,.1f} more hours at this rate')
        elif ex:
            print(f'\nthe last {TAIL} points do not fall: no extrapolation to {args.target} cm')
    if args.figure:
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(7, 4))
        for name, run in out.items():
            ax.plot([r['samples'] / 1e6 for r in run['rows']],
                    [r['dist_cm'] for r in run['rows']], marker='o', label=name)
        if args.target is not None:
            ax.axhline(args.target, color='grey', linestyle='--', label='target')
        ax.set_xlabel('samples seen in this run [M]')
        ax.set_ylabel('validation distance, own index [cm]')
        ax.set_xscale('log')
        ax.grid(True, alpha=0.3)
        ax.legend()
        fig.tight_layout()
        fig.savefig(args.figure, dpi=110)
        print(f'\nwrote {args.figure}')
    write_json(args.json, 'campaign', out)
    return 0


if __name__ == '__main__':
    sys.exit(main())
