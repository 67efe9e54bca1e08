"""``sik-chain``: export an arm's chain file, for training where there is no Pinocchio."""

import argparse
import json
from pathlib import Path
from typing import List, Optional

from sik_ros.cli import argv_or_default, Parser, run_cli
from sik_ros.cli.common import add_robot_args, robot_from_args


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of sik-chain."""
    p = Parser(prog='sik-chain', description='Write an arm\'s chain file: its chain arrays, '
               'joint limits, names and robot manifest (a few kB of JSON). sik-train --chain '
               'trains from it on a machine with torch and NumPy alone (a GPU machine), and '
               'its models fit the robot here.')
    add_robot_args(p)
    p.add_argument('--bundle', help='the robot of this bundle (a directory or a bundled name, '
                   'e.g. panda) instead of --robot/--urdf')
    p.add_argument('--out', required=True, help='chain file to write (JSON)')
    return p


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of sik-chain."""
    args = build_parser().parse_args(argv_or_default(argv))

    def body() -> int:
        from sik_ros.kinematics.chain_file import load_chain_file, write_chain_file
        if args.bundle:
            from sik_ros.bundles.bundle import read_bundle_manifest, resolve_bundle
            from sik_ros.kinematics.robots import robot_from_manifest
            path = resolve_bundle(args.bundle)
            robot = robot_from_manifest(read_bundle_manifest(path)['robot'], f'bundle {path}')
        else:
            robot = robot_from_args(args)
        out = write_chain_file(robot, Path(args.out))
        arm = load_chain_file(out)  # as the training machine will read it
        print(json.dumps({'chain_file': str(out), 'robot': arm.name, 'joints': arm.dof,
                          'base_frame': robot.base_frame, 'tip_frame': robot.tip_frame,
                          'bytes': out.stat().st_size}))
        return 0
    return run_cli('sik-chain', body)


if __name__ == '__main__':
    raise SystemExit(main())
