"""``sik-collect``: sweep the joints (Algorithm 1) and record tip poses with Pinocchio FK."""

import argparse
import time
from typing import List, Optional

from tqdm import tqdm

from sik_ros.cli import argv_or_default, run_cli
from sik_ros.cli.common import add_robot_args, robot_from_args
from sik_ros.dataset import collect, grid_count
from sik_ros.errors import InvalidArgument


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of sik-collect."""
    p = argparse.ArgumentParser(
        prog='sik-collect', description='Collect an IK training dataset: sweep every joint by '
        '--interval degrees (Algorithm 1) or sample uniformly, and record the tip pose.')
    add_robot_args(p)
    p.add_argument('--sampler', choices=('grid', 'uniform'), default='grid')
    p.add_argument('--interval', type=float, default=30.0,
                   help='grid step per joint [deg] (default: 30, the paper\'s)')
    p.add_argument('--samples', type=int, default=0, help='number of uniform samples')
    p.add_argument('--seed', type=int, default=0, help='seed of the uniform sampler')
    p.add_argument('--out', required=True, help='output dataset directory')
    p.add_argument('--force', action='store_true', help='replace an existing --out')
    p.add_argument('--quiet', action='store_true', help='no progress bar')
    return p


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of sik-collect."""
    args = build_parser().parse_args(argv_or_default(argv))

    def body() -> int:
        robot = robot_from_args(args)
        if args.sampler == 'grid':
            total = grid_count(robot.lower, robot.upper, args.interval)
        else:
            if args.samples < 1:
                raise InvalidArgument(f'--samples must be at least 1; got {args.samples}')
            total = args.samples
        t0 = time.perf_counter()
        with tqdm(total=total, unit='rows', unit_scale=True, disable=args.quiet,
                  desc='collect') as bar:
            ds = collect(robot, args.out, sampler=args.sampler, interval_deg=args.interval,
                         samples=args.samples, seed=args.seed, force=args.force,
                         progress=bar.update)
        print(f'wrote {len(ds)} rows to {ds.path} in {time.perf_counter() - t0:.1f} s')
        return 0
    return run_cli('sik-collect', body)


if __name__ == '__main__':
    raise SystemExit(main())
