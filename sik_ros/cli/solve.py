"""``sik-solve``: solve one IK target from the shell and print the ranked solutions."""

import argparse
from typing import List, Optional

import numpy as np

from sik_ros.cli import argv_or_default, Parser, run_cli
from sik_ros.collision import Obstacle
from sik_ros.solver import dumps, IKResult, SelectiveIK


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of sik-solve."""
    p = Parser(prog='sik-solve', description='Several ranked IK solutions for '
               'one target, from a bundle of trained models.')
    for axis in 'xyz':
        p.add_argument(axis, type=float, help=f'target {axis} in the base frame [m]')
    p.add_argument('--orientation', nargs=4, type=float, metavar=('QX', 'QY', 'QZ', 'QW'),
                   help='target orientation quaternion (default: position-only goal)')
    p.add_argument('--bundle', default='panda', help='bundle name or directory (default: panda)')
    p.add_argument('-n', '--num-solutions', type=int, default=16)
    p.add_argument('--seed', nargs='+', type=float, help='current joint positions [rad]')
    p.add_argument('--box', nargs=6, type=float, action='append', default=[],
                   metavar=('X', 'Y', 'Z', 'SX', 'SY', 'SZ'),
                   help='box obstacle: centre [m] and side lengths [m]; repeatable')
    p.add_argument('--sphere', nargs=4, type=float, action='append', default=[],
                   metavar=('X', 'Y', 'Z', 'R'), help='sphere obstacle; repeatable')
    p.add_argument('--no-refine', action='store_true', help='raw decoded solutions')
    p.add_argument('--timeout', type=float, help='[s]')
    p.add_argument('--json', action='store_true', help='print the result as JSON')
    return p


def format_table(res: IKResult, joint_names: List[str]) -> str:
    """A readable table of ranked solutions."""
    lines = [f"{'#':>2} {'pos err [mm]':>12} {'rot err [deg]':>13} {'clearance':>9} "
             f"{'score':>8}  q [rad] ({', '.join(n.split('_')[-1] for n in joint_names)})"]
    for i, s in enumerate(res.solutions, 1):
        clear = '-' if not np.isfinite(s.min_obstacle_distance) else \
            f'{s.min_obstacle_distance:.3f}'
        lines.append(f'{i:>2} {s.position_error * 1e3:>12.4f} '
                     f'{np.degrees(s.orientation_error):>13.4f} {clear:>9} {s.score:>8.3f}  '
                     + ' '.join(f'{v:+.3f}' for v in s.q))
    head = (f"{'success' if res.success else 'FAILED'}: {len(res.solutions)} solutions for a "
            f'{res.goal} goal in {res.elapsed * 1e3:.1f} ms')
    return head + ('' if not res.message else f' ({res.message})') + '\n' + '\n'.join(lines)


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of sik-solve."""
    args = build_parser().parse_args(argv_or_default(argv))

    def body() -> int:
        ik = SelectiveIK.load(args.bundle)
        obstacles = [Obstacle('box', tuple(b[3:]), tuple(b[:3])) for b in args.box]
        obstacles += [Obstacle('sphere', (s[3],), tuple(s[:3])) for s in args.sphere]
        res = ik.solve((args.x, args.y, args.z), args.orientation, args.num_solutions,
                       seed=args.seed, obstacles=obstacles, refine=not args.no_refine,
                       timeout=args.timeout)
        print(dumps(res, ik.joint_names) if args.json else format_table(res, ik.joint_names))
        return 0 if res.success else 1
    return run_cli('sik-solve', body)


if __name__ == '__main__':
    raise SystemExit(main())
