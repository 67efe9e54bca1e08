"""``sik-eval``: reproduce the paper's experiments; write ``results.md`` and PNG figures.

    sik-eval --out docs/                         # everything on the bundled models (minutes)
    sik-eval --quick --bundle DIR --out /tmp/e   # a reduced run (seconds)

The experiments, the report and the figures are in :mod:`sik_ros.eval`; this module parses the
flags, shows the progress and writes the files.
"""

import argparse
import datetime
from pathlib import Path
import sys
from typing import List, Optional

from sik_ros.cli import argv_or_default, Parser, run_cli
from sik_ros.errors import CorruptArtifact, InvalidArgument


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of sik-eval."""
    p = Parser(prog='sik-eval', description='Reproduce the experiments of the '
               'Selective IK paper and write a report with tables and figures.')
    p.add_argument('--out', default='docs', help='report folder: results.md, results.json and '
                   'figures/ (default: docs)')
    p.add_argument('--bundle', default='panda', help='bundle name or directory (default: panda)')
    p.add_argument('--baselines', help='folder with psik.pt (or a psik/ bundle), fcn.pt, '
                   'fcn_uni.pt, anfis.pt; missing ones are reported as not provided')
    p.add_argument('--latent-study', help='folder with latent_<d>.pt checkpoints (d = 1..7)')
    p.add_argument('--quick', action='store_true', help='a reduced run: few targets and radii')
    p.add_argument('--targets', type=int, help='targets per radius and over the workspace '
                   '(default: 100, quick: 5)')
    p.add_argument('--samples', type=int, help='joint samples searched for targets near each '
                   'radius (default: 1,000,000, quick: 100,000)')
    p.add_argument('--seed', type=int, default=0, help='seed of the target sampling')
    p.add_argument('--threads', type=int, default=1, help='torch threads (default: 1)')
    p.add_argument('--quiet', action='store_true', help='no progress bar')
    return p


def check_args(args: argparse.Namespace) -> None:
    """Refuse flag values the run cannot use.

    Raises:
        InvalidArgument: a count out of range or a folder that does not exist.
    """
    if args.targets is not None and args.targets < 1:
        raise InvalidArgument(f'--targets must be at least 1; got {args.targets}')
    if args.samples is not None and args.samples < 1000:
        raise InvalidArgument(f'--samples must be at least 1000; got {args.samples}')
    if args.threads < 1:
        raise InvalidArgument(f'--threads must be at least 1; got {args.threads}')
    for flag, folder in (('--baselines', args.baselines), ('--latent-study', args.latent_study)):
        if folder is not None and not Path(folder).is_dir():
            raise InvalidArgument(f'{flag} {folder}: not a directory')


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of sik-eval."""
    argv = argv_or_default(argv)
    args = build_parser().parse_args(argv)

    def body() -> int:
        import torch
        from tqdm import tqdm

        from sik_ros.artifacts import write_text_atomic
        from sik_ros.eval import (load_baselines, report, run_evaluation, Settings,
                                  summary_json)
        from sik_ros.solver import SelectiveIK
        check_args(args)
        torch.set_num_threads(args.threads)
        start = datetime.datetime.now()
        settings = Settings.of(args.quick, args.targets, args.samples, args.seed,
                               args.latent_study)
        out = Path(args.out)
        ik = SelectiveIK.load(args.bundle)
        if 'position' not in ik.goals:
            raise InvalidArgument(f'bundle {ik.bundle} has no position model; the experiments '
                                  'need one')
        baselines, missing = load_baselines(args.baselines, ik.robot)
        refused = {k: v for k, v in missing.items() if v.startswith('refused')}
        if refused:
            # a shipped model that does not load would silently drop its columns
            raise CorruptArtifact('; '.join(f'{k}: {v}' for k, v in sorted(refused.items())))
        out.mkdir(parents=True, exist_ok=True)
        with tqdm(total=1, disable=args.quiet, mininterval=1.0, file=sys.stderr) as bar:
            res = run_evaluation(ik, baselines, settings, out / 'figures', bar)
        res.date = start.strftime('%Y-%m-%d %H:%M')
        res.elapsed_s = (datetime.datetime.now() - start).total_seconds()
        write_text_atomic(out / 'results.md', report(res, ik, baselines, missing, argv))
        write_text_atomic(out / 'results.json', summary_json(res))
        print(f'wrote {out / "results.md"}, {out / "results.json"} and {len(res.figures)} '
              f'figures in {out / "figures"}')
        return 0
    return run_cli('sik-eval', body)


if __name__ == '__main__':
    raise SystemExit(main())
