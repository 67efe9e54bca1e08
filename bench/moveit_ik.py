"""Benchmark of sik_node's ``/compute_ik`` beside ``~/solve_ik`` and an empty service, paired.

For pose goals at FK of random Panda configurations, each goal is sent, in turn (A B C, goal by
goal, so that all three see the same machine):

- to ``~/solve_ik`` for one solution (``max_solutions: 1``), seeded with the arm's joints;
- to ``/compute_ik`` as MoveIt user code sends it (group ``panda_arm``, the whole robot's state
  with the finger joints as seed, ``avoid_collisions`` as ``--avoid-collisions`` says);
- to the empty ``std_srvs/Trigger`` service of ``bench/empty_service.py`` (the floor of a round
  trip), a process beside the node;

all three from background-spun clients of this process, each with a 50 ms timeout where it has
one. Prints the round trips (p50, p90, p99) [ms], the ratio of ``/compute_ik`` to
``~/solve_ik`` (of the p50s, and the median of the per-goal ratios), and how many answers were
SUCCESS; the figures are never asserted (docs/benchmarks.md).

Usage: ``python bench/moveit_ik.py [--requests N] [--avoid-collisions] [--domain ID]
[--json PATH]``.
"""

import argparse
import os
import subprocess
import sys
import time
from typing import List, Optional

from builtin_interfaces.msg import Duration
from moveit_msgs.msg import MoveItErrorCodes
from moveit_msgs.srv import GetPositionIK
import numpy as np
import rclpy
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from sik_interfaces.srv import SolveIK
from sik_ros.kinematics.robots import load_robot
from sik_ros.ros import client as ros_client, launch
from sik_ros.ros.client import SolveIKClient

import empty_service  # noqa: I100 (bench/empty_service.py)
from report import add_json_argument, write_json  # noqa: I100 (bench/report.py)
from service import start_floor  # noqa: I100 (bench/service.py)

TIMEOUT = Duration(sec=0, nanosec=50_000_000)
FINGERS = ('panda_finger_joint1', 'panda_finger_joint2')
GROUP = 'panda_arm'


def goals(count: int, seed: int = 0):
    """Pose goals of random Panda configurations and a seed for each: (p, quat, seed) rows."""
    robot = load_robot('panda')
    rng = np.random.default_rng(seed)
    q = rng.uniform(robot.lower, robot.upper, (count, robot.dof))
    pos, quat = robot.fk_batch(q)
    seeds = rng.uniform(robot.lower, robot.upper, (count, robot.dof))
    return robot.joint_names, [(pos[i], quat[i], seeds[i]) for i in range(count)]


def requests(names: List[str], goal, avoid: bool):
    """The ``~/solve_ik`` and ``/compute_ik`` requests of one goal."""
    p, quat, seed = goal
    solve = ros_client.pose_request(p, quat, max_solutions=1)
    solve.seed = JointState(name=list(names), position=[float(v) for v in seed])
    solve.timeout = TIMEOUT
    ik = GetPositionIK.Request()
    req = ik.ik_request
    req.group_name, req.avoid_collisions, req.timeout = GROUP, avoid, TIMEOUT
    req.robot_state.joint_state = JointState(name=list(names) + list(FINGERS),
                                             position=[float(v) for v in seed] + [0.02, 0.02])
    req.pose_stamped.header.frame_id = 'panda_link0'
    req.pose_stamped.pose = solve.target.pose
    return solve, ik


def paired(sik: SolveIKClient, moveit: SolveIKClient, floor: SolveIKClient, names, rows,
           avoid: bool):
    """Round trips [s] of the three services, goal by goal in turn, and the SUCCESS counts."""
    times = {'solve_ik': [], 'compute_ik': [], 'floor': []}
    ok = {'solve_ik': 0, 'compute_ik': 0}
    nothing = Trigger.Request()
    for goal in rows:
        solve, ik = requests(names, goal, avoid)
        t0 = time.perf_counter()
        a = sik.call(solve)
        t1 = time.perf_counter()
        b = moveit.call(ik)
        t2 = time.perf_counter()
        floor.call(nothing)
        t3 = time.perf_counter()
        times['solve_ik'].append(t1 - t0)
        times['compute_ik'].append(t2 - t1)
        times['floor'].append(t3 - t2)
        ok['solve_ik'] += a is not None and a.error_code == SolveIK.Response.SUCCESS
        ok['compute_ik'] += b is not None and b.error_code.val == MoveItErrorCodes.SUCCESS
    return times, ok


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--requests', type=int, default=2000, help='goals (default 2000)')
    parser.add_argument('--avoid-collisions', action='store_true',
                        help='/compute_ik requests ask for collision-free answers')
    parser.add_argument('--domain', type=int, help='ROS_DOMAIN_ID (default: a random one)')
    add_json_argument(parser)
    args = parser.parse_args(argv)
    names, rows = goals(args.requests)
    _, warm = goals(20, seed=1)
    env = launch.ros_env(args.domain)
    proc = launch.launch_node(None, env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.STDOUT)
    floor_proc = start_floor(env)
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    try:
        with SolveIKClient('/sik_node/solve_ik', 'bench_solve_ik') as sik, \
                SolveIKClient('/compute_ik', 'bench_compute_ik',
                              srv_type=GetPositionIK) as moveit, \
                SolveIKClient(empty_service.SERVICE, 'bench_floor', srv_type=Trigger) as floor:
            if not all(c.wait_for_service(90.0) for c in (sik, moveit, floor)):
                print(f'a service did not come up (node exit code {proc.poll()})')
                return 1
            paired(sik, moveit, floor, names, warm, args.avoid_collisions)
            times, ok = paired(sik, moveit, floor, names, rows, args.avoid_collisions)
    finally:
        launch.stop_node(floor_proc)
        launch.stop_node(proc)
        rclpy.try_shutdown()
    pct = {k: dict(zip(('p50_ms', 'p90_ms', 'p99_ms'),
                       (float(v) for v in np.percentile(np.asarray(t) * 1e3, [50, 90, 99]))))
           for k, t in times.items()}
    per_goal = np.asarray(times['compute_ik']) / np.asarray(times['solve_ik'])
    data = {'requests': args.requests, 'avoid_collisions': args.avoid_collisions,
            'round_trip': pct, 'success': ok,
            'ratio_p50': pct['compute_ik']['p50_ms'] / pct['solve_ik']['p50_ms'],
            'paired_ratio_median': float(np.median(per_goal)),
            'load_average': list(os.getloadavg())}
    write_json(args.json, 'moveit_ik', data)
    print(f'sik_node /compute_ik and ~/solve_ik (one solution), bundled Panda, pose goals, '
          f'{args.requests} goals in turn, 50 ms timeout, avoid_collisions '
          f'{args.avoid_collisions}; load average {os.getloadavg()[0]:.2f}')
    print('| service | p50 / p90 / p99 [ms] | SUCCESS |')
    print('|---|---|---|')
    for key, label in (('solve_ik', '~/solve_ik, 1 solution'), ('compute_ik', '/compute_ik'),
                       ('floor', 'empty Trigger service')):
        p = pct[key]
        success = f'{ok[key]}/{args.requests}' if key in ok else ''
        print(f'| {label} | {p["p50_ms"]:.2f} / {p["p90_ms"]:.2f} / {p["p99_ms"]:.2f} | '
              f'{success} |')
    print(f'/compute_ik / ~/solve_ik: p50 ratio {data["ratio_p50"]:.2f}, median of per-goal '
          f'ratios {data["paired_ratio_median"]:.2f} (target <= 1.3)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
