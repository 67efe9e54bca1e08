"""``sik-reach``: an arm's reachability map (pose goals over voxels and orientations)."""

import argparse
from pathlib import Path
from typing import List, Optional

from sik_ros.cli import argv_or_default, Parser, run_cli
from sik_ros.errors import InvalidArgument


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of sik-reach."""
    p = Parser(prog='sik-reach', description='Reachability map of an arm: K orientations at '
               'every voxel centre of its reach, each pose goal solved; resumable.')
    arm = p.add_mutually_exclusive_group(required=True)
    arm.add_argument('--robot', help='a bundled model (panda) or an example-robot-data name '
                     '(served by a table of configurations)')
    arm.add_argument('--bundle', help='a bundle directory')
    arm.add_argument('--urdf', help='a URDF file (with --base and --tip)')
    p.add_argument('--base', help='--urdf: base frame')
    p.add_argument('--tip', help='--urdf: tip frame')
    p.add_argument('--voxel', type=float, default=0.05, help='voxel edge [m] (default 0.05)')
    p.add_argument('--orientations', type=int, default=64,
                   help='orientations per voxel, spread over SO(3) (default 64)')
    p.add_argument('-n', '--num-solutions', type=int, default=16,
                   help='solutions asked per goal (default 16)')
    p.add_argument('--timeout', type=float, help='each goal\'s budget [s]')
    p.add_argument('--out', default='reach', help='output folder (default: reach)')
    p.add_argument('--workers', type=int, help='processes, or Ray workers with --ray (default: '
                   'every core, or every CPU of the cluster)')
    p.add_argument('--ray', metavar='ADDRESS',
                   help='solve on a Ray cluster: auto (one running on this network), '
                   'HOST:6379, ray://HOST:10001, or local (start one here); needs '
                   'pip install "sik_ros[ray]"')
    return p


def load_solver(args):
    """The solver the arguments name: a bundle, or a table of configurations for a URDF."""
    from sik_ros.bundles.bundle import BUNDLES
    from sik_ros.solver import SelectiveIK
    if args.bundle or (args.robot and (BUNDLES / args.robot).is_dir()):
        return SelectiveIK.load(args.bundle or args.robot)
    if args.urdf and not (args.base and args.tip):
        raise InvalidArgument('--urdf needs --base and --tip')
    from sik_ros.bundles.sweep_models import sweep_models
    from sik_ros.kinematics.robots import load_robot
    robot = load_robot(args.robot or 'panda', args.urdf, args.base, args.tip)
    return SelectiveIK(robot, sweep_models(robot))


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of sik-reach."""
    args = build_parser().parse_args(argv_or_default(argv))

    def body() -> int:
        from tqdm import tqdm
        from sik_ros.solver.reach_map import (build_reach_map, load_reach_map, plot_reach_map,
                                              ReachSettings)
        if args.orientations < 1:
            raise InvalidArgument(f'--orientations must be at least 1; got {args.orientations}')
        ik = load_solver(args)
        settings = ReachSettings(voxel=args.voxel, orientations=args.orientations,
                                 num_solutions=args.num_solutions, timeout=args.timeout)
        bar = tqdm(unit='goal', desc='sik-reach')

        def progress(done: int, total: int) -> None:
            bar.total = total
            bar.update(done - bar.n)

        executor = None
        if args.ray:
            from sik_ros.solver.cluster import RayExecutor
            executor = RayExecutor(None if args.ray == 'local' else args.ray, args.workers)
        try:
            path = build_reach_map(ik, Path(args.out), settings, args.workers, progress,
                                   executor)
        finally:
            bar.close()
            if executor is not None:
                executor.close()
        data = load_reach_map(path)
        plot_reach_map(data, Path(args.out) / 'reach.png')
        reach = data['reachability']
        print(f'{path}: {len(reach)} voxels x {settings.orientations} orientations, '
              f'{data["success"].mean():.1%} of the pose goals reached, '
              f'{(reach > 0).mean():.1%} of the voxels reached at some orientation')
        return 0
    return run_cli('sik-reach', body, on_stop='the chunks written are kept: run it again to '
                   'continue')


if __name__ == '__main__':
    raise SystemExit(main())
