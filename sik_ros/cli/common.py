"""Arguments shared by several CLIs."""

import argparse
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # loaded when a robot is: Pinocchio
    from sik_ros.kinematics.robot import Robot


def add_robot_args(parser: argparse.ArgumentParser) -> None:
    """Add ``--robot``, ``--urdf``, ``--base`` and ``--tip``."""
    parser.add_argument('--robot', default='panda',
                        help='example-robot-data robot name (default: panda)')
    parser.add_argument('--urdf', help='URDF file instead of a named robot (needs --base/--tip)')
    parser.add_argument('--base', help='base frame (default: the robot\'s, e.g. panda_link0)')
    parser.add_argument('--tip', help='tip frame (default: the robot\'s, e.g. panda_hand_tcp)')


def robot_from_args(args: argparse.Namespace) -> 'Robot':
    """Load the robot the arguments name."""
    from sik_ros.kinematics.robots import load_robot
    return load_robot(args.robot, args.urdf, args.base, args.tip)
