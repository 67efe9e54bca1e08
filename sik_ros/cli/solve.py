"""``sik-solve``: solve one IK target from the shell and print the ranked solutions."""

import argparse
from pathlib import Path
from typing import List, Optional, Tuple, TYPE_CHECKING

import numpy as np

from sik_ros.cli import argv_or_default, Parser, run_cli
from sik_ros.errors import InvalidArgument
from sik_ros.solver.config import PATH_DEFAULTS
from sik_ros.solver.results import dumps, family_label, IKResult, tier_label

if TYPE_CHECKING:  # loaded in main(): it brings torch and Pinocchio
    from sik_ros.solver.selective_ik import SelectiveIK


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of sik-solve."""
    p = Parser(prog='sik-solve', description='Several ranked IK solutions for '
               'one target, from a bundle of trained models.')
    for axis in 'xyz':
        p.add_argument(axis, type=float, nargs='?',
                       help=f'target {axis} in the base frame [m] (not with --path)')
    p.add_argument('--path', help='a Cartesian path instead: CSV (x,y,z[,qx,qy,qz,qw] per row) '
                   'or YAML (a list of [x, y, z(, qx, qy, qz, qw)]) of waypoints [m]')
    p.add_argument('--targets', help='many targets instead: CSV or NPZ rows x y z '
                   '[qx qy qz qw] [m], solved on every core (one line each)')
    p.add_argument('--out', help='--targets: write the answers to this NPZ (solutions padded '
                   'with NaN, a manifest)')
    p.add_argument('--workers', type=int, help='--targets: processes (default: every core)')
    p.add_argument('--max-joint-step', type=float, default=PATH_DEFAULTS.max_joint_step,
                   help='--path: largest joint change between waypoints [rad]')
    p.add_argument('--paths', type=int, default=PATH_DEFAULTS.num_paths,
                   help='--path: ranked paths at most')
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
    p.add_argument('--one-per-family', action='store_true',
                   help='at most one solution per posture family (the best of each)')
    p.add_argument('--timeout', type=float, help='[s]')
    p.add_argument('--json', action='store_true', help='print the result as JSON')
    return p


def short_names(names: List[str]) -> List[str]:
    """Joint names without the ``_``-separated words they all share at the start or the end.

    ``panda_joint1`` ... gives ``joint1`` ..., ``shoulder_pan_joint`` ... ``shoulder_pan`` ...;
    the names themselves when that would leave an empty or a repeated one.
    """
    if len(names) < 2:
        return list(names)
    words = [n.split('_') for n in names]
    start = 0
    while all(len(w) > start + 1 and w[start] == words[0][start] for w in words):
        start += 1
    end = 0
    while all(len(w) > start + end + 1 and w[-1 - end] == words[0][-1 - end] for w in words):
        end += 1
    short = ['_'.join(w[start:len(w) - end]) for w in words]
    return short if len(set(short)) == len(short) and all(short) else list(names)


def format_table(res: IKResult, joint_names: List[str]) -> str:
    """A readable table of ranked solutions."""
    lines = [f"{'#':>2} {'pos err [mm]':>12} {'rot err [deg]':>13} {'clearance':>9} "
             f"{'tier':>10} {'family':>6} {'score':>8}  "
             f"q [rad] ({', '.join(short_names(joint_names))})"]
    for i, s in enumerate(res.solutions, 1):
        clear = '-' if not np.isfinite(s.min_obstacle_distance) else \
            f'{s.min_obstacle_distance:.3f}'
        lines.append(f'{i:>2} {s.position_error * 1e3:>12.4f} '
                     f'{np.degrees(s.orientation_error):>13.4f} {clear:>9} '
                     f'{tier_label(s.tier, s.self_collision):>10} {family_label(s):>6} '
                     f'{s.score:>8.3f}  '
                     + ' '.join(f'{v:+.3f}' for v in s.q))
    head = (f"{'success' if res.success else 'FAILED'}: {len(res.solutions)} solutions for a "
            f'{res.goal} goal in {res.elapsed * 1e3:.1f} ms, {res.num_families} '
            f"famil{'y' if res.num_families == 1 else 'ies'} found")
    return head + ('' if not res.message else f' ({res.message})') + '\n' + '\n'.join(lines)


def read_waypoints(path: str) -> Tuple[np.ndarray, Optional[np.ndarray]]:
    """Positions (N, 3) and quaternions (N, 4) or None from a CSV or YAML file.

    Raises:
        InvalidArgument: unreadable, or rows that are not 3 or 7 numbers alike.
    """
    file = Path(path)
    try:
        text = file.read_text()
        if file.suffix in ('.yaml', '.yml'):
            import yaml
            rows = yaml.safe_load(text)
        else:
            rows = [[float(v) for v in line.replace(',', ' ').split()]
                    for line in text.splitlines() if line.strip() and not line.startswith('#')]
        arr = np.array(rows, dtype=float)
    except (OSError, ValueError, TypeError) as exc:
        raise InvalidArgument(f'cannot read waypoints from {file}: {exc}') from exc
    except Exception as exc:  # YAML syntax errors and the like
        raise InvalidArgument(f'cannot read waypoints from {file}: {type(exc).__name__}') \
            from exc
    if arr.ndim != 2 or arr.shape[1] not in (3, 7):
        raise InvalidArgument(f'{file}: each waypoint needs 3 (x y z) or 7 (x y z qx qy qz qw) '
                              f'numbers; got shape {arr.shape}')
    return arr[:, :3], (arr[:, 3:] if arr.shape[1] == 7 else None)


def solve_path_file(ik: 'SelectiveIK', args) -> int:
    """``--path``: plan through the file's waypoints and print the ranked paths."""
    positions, quats = read_waypoints(args.path)
    res = ik.solve_path(positions, quats, seed=args.seed, num_paths=args.paths,
                        max_joint_step=args.max_joint_step, timeout=args.timeout)
    print(f"{'success' if res.success else 'FAILED'}: {len(res.paths)} paths through "
          f"{len(positions)} waypoints, fraction {res.fraction:.3f}, "
          f"{res.elapsed * 1e3:.1f} ms" + (f' ({res.message})' if res.message else ''))
    print(f"{'#':>2} {'waypoints':>9} {'max step [rad]':>14} {'travel [rad]':>12} "
          f"{'max err [mm]':>12} {'cost':>8}")
    for i, jp in enumerate(res.paths, 1):
        print(f'{i:>2} {len(jp.q):>9} {jp.max_step:>14.3f} {jp.travel:>12.3f} '
              f'{1e3 * jp.position_errors.max():>12.4f} {jp.cost:>8.3f}')
    return 0 if res.success else 1


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of sik-solve."""
    args = build_parser().parse_args(argv_or_default(argv))

    def body() -> int:
        if args.path is None and args.targets is None and None in (args.x, args.y, args.z):
            raise InvalidArgument('give a target x y z, --targets FILE or --path FILE')
        if args.targets is not None:
            from sik_ros.cli.targets import read_targets
            read_targets(args.targets)  # a bad file is refused before the bundle loads
        from sik_ros.kinematics.collision import Obstacle
        from sik_ros.solver import SelectiveIK
        ik = SelectiveIK.load(args.bundle)
        if args.path is not None:
            return solve_path_file(ik, args)
        if args.targets is not None:
            from sik_ros.cli.targets import solve_targets
            return solve_targets(ik, args)
        obstacles = [Obstacle('box', tuple(b[3:]), tuple(b[:3])) for b in args.box]
        obstacles += [Obstacle('sphere', (s[3],), tuple(s[:3])) for s in args.sphere]
        res = ik.solve((args.x, args.y, args.z), args.orientation, args.num_solutions,
                       seed=args.seed, obstacles=obstacles, refine=not args.no_refine,
                       timeout=args.timeout, one_per_family=args.one_per_family or None)
        print(dumps(res, ik.joint_names) if args.json else format_table(res, ik.joint_names))
        return 0 if res.success else 1
    return run_cli('sik-solve', body)


if __name__ == '__main__':
    raise SystemExit(main())
