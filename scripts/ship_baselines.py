#!/usr/bin/env python3
"""Ship the trained baselines with the Panda bundle: ``sik_ros/bundles/panda/baselines``.

Takes the runs of ``scripts/train_baselines.sh`` (PSIK's checkpoint, the FCNs' and ANFIS's
exported models), builds PSIK's index table over the 30-degree dataset as the bundled SIK
position model's is built (the indices its decoder realises marked, 1.5 cm), with 12 indices
per cell and no orientations (PSIK answers position goals), and writes the folder with its
manifest (``baselines.json``, :mod:`sik_ros.eval.shipped`) under a temporary name, renamed
into place. ``sik-eval --baselines sik_ros/bundles/panda/baselines`` (``make paper``) reads it.

    PYTHONPATH=. .venv/bin/python scripts/ship_baselines.py --runs runs --data data/panda30
"""

import argparse
from pathlib import Path
import sys
import tempfile
from typing import List, Optional

from sik_ros.cli import argv_or_default, Parser, run_cli

#: The exported single-solution models, in ``--runs``/baselines (scripts/train_baselines.sh).
SINGLE = ('fcn', 'fcn_uni', 'anfis')


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point."""
    p = Parser(prog='ship_baselines', description=__doc__.split('\n\n')[0])
    p.add_argument('--runs', default='runs', help='the runs folder (default: runs)')
    p.add_argument('--psik', help='PSIK checkpoint (default: RUNS/psik/last.pt)')
    p.add_argument('--psik-bundle', help='a PSIK bundle already built (model and table, as '
                   'this script builds it): shipped as it is, no table built')
    p.add_argument('--data', default='data/panda30', help='the 30-degree dataset')
    p.add_argument('--out', default='sik_ros/bundles/panda/baselines')
    p.add_argument('--figure', help='also draw the shipped models\' training curves (their '
                   'checkpoints\' histories) into this PNG')
    p.add_argument('--only', nargs='*', default=None,
                   help='baselines to ship (default: every one found)')
    args = p.parse_args(argv_or_default(argv))
    return run_cli('ship_baselines', lambda: ship(args))


def ship(args: argparse.Namespace) -> int:
    """Build PSIK's bundle in a temporary folder, then ship it with the other models."""
    from sik_ros.artifacts import read_json
    from sik_ros.cli.index import main as index_main
    from sik_ros.eval.shipped import ship_baselines
    from sik_ros.learning.checkpoints import export_model, load_checkpoint
    runs = Path(args.runs)
    wanted = set(args.only) if args.only is not None else set(SINGLE) | {'psik'}
    models = {n: runs / 'baselines' / f'{n}.pt' for n in SINGLE
              if n in wanted and (runs / 'baselines' / f'{n}.pt').is_file()}
    psik = Path(args.psik) if args.psik else runs / 'psik' / 'last.pt'
    with tempfile.TemporaryDirectory(dir=runs) as tmp:
        bundle = None
        if 'psik' in wanted and args.psik_bundle:
            bundle = Path(args.psik_bundle)
            robot = read_json(bundle / 'bundle.json', 'PSIK bundle')['robot']
        elif 'psik' in wanted and psik.is_file():
            ckpt = load_checkpoint(psik)
            model = export_model(ckpt, Path(tmp) / 'psik_position.pt')
            bundle = Path(tmp) / 'psik'
            rc = index_main(['--model', str(model), '--dataset', args.data,
                             '--out', str(Path(tmp) / 'table.npz'), '--max-tip-error', '0.015',
                             '--max-per-cell', '12', '--no-orientations', '--bundle',
                             str(bundle), '--quiet'])
            if rc != 0:
                return rc
            robot = ckpt['robot']
        elif models:
            robot = load_checkpoint(next(iter(models.values())))['robot']
        else:
            print('ship_baselines: nothing to ship in', runs, file=sys.stderr)
            return 2
        out = ship_baselines(Path(args.out), models, bundle, robot, force=True)
    if args.figure:
        draw_curves(out, Path(args.figure))
    size = sum(f.stat().st_size for f in out.rglob('*') if f.is_file())
    print(f'shipped {sorted(models) + (["psik"] if bundle else [])} to {out} '
          f'({size / 1e6:.1f} MB)')
    return 0


def draw_curves(folder: Path, path: Path) -> Path:
    """Validation distance and loss against step of every model shipped in ``folder``."""
    from sik_ros.eval import plots
    from sik_ros.eval.paper import NAMES
    from sik_ros.eval.shipped import BASELINE_FILES
    from sik_ros.learning.checkpoints import load_checkpoint
    files = {name: folder / f for name, f in BASELINE_FILES.items()}
    files['psik'] = folder / 'psik' / 'sik_position.pt'
    histories = {NAMES[name]: load_checkpoint(f).get('history', [])
                 for name, f in files.items() if f.is_file()}
    return plots.training_curves(histories, path)


if __name__ == '__main__':
    raise SystemExit(main())
