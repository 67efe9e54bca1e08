"""``sik-collect``: sweep the joints (Algorithm 1) and record tip poses with Pinocchio FK."""

import argparse
import time
from typing import List, Optional

from sik_ros.cli import argv_or_default, Parser, run_cli
from sik_ros.cli.common import add_robot_args, robot_from_args
from sik_ros.defaults import MAX_ROWS
from sik_ros.errors import InvalidArgument


def interval_arg(text: str):
    """``auto`` or a number of degrees."""
    if text == 'auto':
        return text
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'must be a number of degrees or auto; got {text!r}')


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of sik-collect."""
    p = Parser(
        prog='sik-collect', description='Collect an IK training dataset: sweep every joint by '
        '--interval degrees (Algorithm 1) or sample uniformly, and record the tip pose. '
        'Periodic joints (a range of a turn or more) are swept over one turn.')
    add_robot_args(p)
    p.add_argument('--sampler', choices=('grid', 'uniform'), default='grid')
    p.add_argument('--interval', type=interval_arg, default=30.0,
                   help='grid step per joint [deg] (default: 30, the paper\'s), or auto: the '
                   'finest step whose grid fits --max-rows')
    p.add_argument('--samples', type=int, default=0, help='number of uniform samples')
    p.add_argument('--seed', type=int, default=0, help='seed of the uniform sampler')
    p.add_argument('--max-rows', type=int, default=MAX_ROWS,
                   help=f'refuse a dataset of more rows (default: {MAX_ROWS:,})')
    p.add_argument('--out', required=True, help='output dataset directory')
    p.add_argument('--force', action='store_true', help='replace an existing --out')
    p.add_argument('--quiet', action='store_true', help='no progress bar')
    return p


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of sik-collect."""
    args = build_parser().parse_args(argv_or_default(argv))

    def body() -> int:
        from tqdm import tqdm

        from sik_ros.tables.dataset import (check_budget, collect, estimate_seconds,
                                            finest_interval, free_disk, grid_count, row_bytes)
        robot = robot_from_args(args)
        print(f'robot {robot.name}: {robot.dof} joints, base {robot.base_frame}, tip '
              f'{robot.tip_frame}; periodic: '
              f'{[n for n, p in zip(robot.joint_names, robot.periodic) if p] or "none"}')
        if args.sampler == 'grid':
            if args.interval == 'auto':
                args.interval = finest_interval(robot, args.max_rows)
                if args.interval is None:
                    raise InvalidArgument(f'no grid interval fits --max-rows {args.max_rows:,}; '
                                          f'use --sampler uniform')
            total = grid_count(robot.lower, robot.upper, args.interval, robot.periodic)
            what = f'grid at {args.interval:g} deg'
        else:
            if args.samples < 1:
                raise InvalidArgument(f'--samples must be at least 1; got {args.samples}')
            total, what = args.samples, 'uniform sampler'
        print(f'{what}: {total:,} rows, {total * row_bytes(robot) / 1e6:,.0f} MB, about '
              f'{estimate_seconds(robot, total):,.0f} s')
        check_budget(robot, total, args.max_rows, free_disk(args.out), args.sampler)
        t0 = time.perf_counter()
        with tqdm(total=total, unit='rows', unit_scale=True, disable=args.quiet,
                  desc='collect') as bar:
            ds = collect(robot, args.out, sampler=args.sampler, interval_deg=args.interval,
                         samples=args.samples, seed=args.seed, force=args.force,
                         progress=bar.update, max_rows=args.max_rows)
        print(f'wrote {len(ds)} rows to {ds.path} in {time.perf_counter() - t0:.1f} s')
        return 0
    return run_cli('sik-collect', body)


if __name__ == '__main__':
    raise SystemExit(main())
