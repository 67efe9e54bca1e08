"""The README's main command (``make run``): sik_node answering IK requests, end to end.

Starts ``sik_node`` as a subprocess on a fresh ROS domain, sends goals through the service
``/sik_node/solve_ik`` (a position goal, a pose goal, one with a seed, one with a box obstacle)
and one through the topic ``/sik_node/goal`` (answer on ``/sik_node/solutions``), prints each
answer as a ranked table, then stops the node with SIGINT. Exit code 0 when every request was
answered and the node shut down cleanly.

Starting and stopping the node: :mod:`sik_ros.ros.launch`; requests: :mod:`sik_ros.ros.client`.
"""

import argparse
import time
from typing import List, Optional, Sequence

from geometry_msgs.msg import PoseStamped
import numpy as np
import rclpy
from rclpy.node import Node

from sik_interfaces.msg import IKSolution, IKSolutionArray
from sik_interfaces.srv import SolveIK, SolvePath
from sik_ros.ros.client import box, pose_request, SolveIKClient
from sik_ros.ros.conversions import ERROR_NAMES
from sik_ros.ros.launch import (bundle_goals, launch_node, NODE, ros_env, stop_node,
                                wait_for_service)
from sik_ros.solver.results import tier_label

#: Arm configurations whose tip poses serve as reachable demo targets [rad].
READY = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)
REACH_LEFT = (0.5, -0.3, 0.2, -2.0, 0.1, 1.9, 0.6)
REACH_LOW = (0.0, 0.4, 0.0, -2.0, 0.0, 2.4, 0.8)
REACH_RIGHT = (-0.4, 0.3, 0.0, -1.9, 0.0, 2.2, 0.8)
#: Codes that answer a valid request (a model may fail to solve a target; that is not a crash).
ANSWERED = (SolveIK.Response.SUCCESS, SolveIK.Response.NO_SOLUTION, SolveIK.Response.TIMEOUT)


def format_answer(title: str, answer, seconds: Optional[float] = None, rows: int = 8) -> str:
    """Format a SolveIK response or an IKSolutionArray as a readable ranked table."""
    code = ERROR_NAMES.get(answer.error_code, str(answer.error_code))
    took = '' if seconds is None else f', {seconds * 1e3:.1f} ms round trip'
    lines = [f'== {title}: {code}{took}', f'   {answer.message}']
    if not answer.solutions:
        return '\n'.join(lines)
    names = [n.split('_')[-1] for n in answer.solutions[0].joint_state.name]
    lines.append(f"   {'rank':>4} {'pos err [mm]':>12} {'rot err [deg]':>13} "
                 f"{'clearance [m]':>13} {'tier':>10} {'family':>6} {'score':>8}  "
                 f"joints [rad] ({' '.join(names)})")
    for rank, s in enumerate(answer.solutions[:rows], 1):
        clear = '-' if not np.isfinite(s.min_obstacle_distance) else \
            f'{s.min_obstacle_distance:.3f}'
        family = '-' if s.family == IKSolution.NO_FAMILY else str(s.family)
        lines.append(f'   {rank:>4} {s.position_error * 1e3:>12.4f} '
                     f'{np.degrees(s.orientation_error):>13.4f} {clear:>13} '
                     f'{tier_label(s.tier, s.self_collision):>10} {family:>6} {s.score:>8.3f}  '
                     + ' '.join(f'{v:+.3f}' for v in s.joint_state.position))
    if len(answer.solutions) > rows:
        lines.append(f'   ... and {len(answer.solutions) - rows} more')
    return '\n'.join(lines)


def topic_goal(node: Node, position: Sequence[float], timeout: float = 10.0):
    """Publish a PoseStamped on ``~/goal``; the IKSolutionArray from ``~/solutions`` or None."""
    got: List[IKSolutionArray] = []
    sub = node.create_subscription(IKSolutionArray, f'{NODE}/solutions', got.append, 10)
    pub = node.create_publisher(PoseStamped, f'{NODE}/goal', 10)
    deadline = time.monotonic() + timeout
    while (pub.get_subscription_count() == 0 or sub.get_publisher_count() == 0) \
            and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.05)
    msg = PoseStamped()
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(v) for v in position)
    pub.publish(msg)
    while not got and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.05)
    node.destroy_subscription(sub)
    node.destroy_publisher(pub)
    return got[0] if got else None


def path_demo(robot, pose: bool) -> bool:
    """Plan a straight line and a circle through ``~/solve_path`` and print the ranked paths."""
    with SolveIKClient(f'{NODE}/solve_path', 'sik_demo_paths', srv_type=SolvePath) as client:
        if not client.wait_for_service(10.0):
            print('== ~/solve_path: not available')
            return False
        return _paths(client, robot, pose)


def _paths(client: SolveIKClient, robot, pose: bool) -> bool:
    p0, quat = robot.fk(np.array(READY))
    t = np.linspace(0, 1, 30)
    shapes = (('straight line, 30 cm along y', p0 + t[:, None] * [0.0, 0.3, 0.0]),
              ('circle, radius 10 cm in the horizontal plane',
               p0 + 0.1 * np.stack([np.cos(2 * np.pi * t) - 1, np.sin(2 * np.pi * t),
                                    0 * t], axis=1)))
    ok = True
    for title, points in shapes:
        req = SolvePath.Request(use_orientation=pose, velocity_scaling=0.5)
        for point in points:
            w = PoseStamped()
            w.pose.position.x, w.pose.position.y, w.pose.position.z = map(float, point)
            (w.pose.orientation.x, w.pose.orientation.y, w.pose.orientation.z,
             w.pose.orientation.w) = map(float, quat)
            req.waypoints.append(w)
        req.seed.name, req.seed.position = list(robot.joint_names), [float(v) for v in READY]
        req.timeout.sec = 5
        t0 = time.perf_counter()
        answer = client.call(req, 30.0)
        took = time.perf_counter() - t0
        kind = 'pose' if pose else 'position'
        if answer is None:
            print(f'== path ({kind}): {title}: no answer')
            ok = False
            continue
        print(f'== path ({kind}): {title}, {len(points)} waypoints: '
              f'{ERROR_NAMES.get(answer.error_code, answer.error_code)}, fraction '
              f'{answer.fraction:.2f}, {took * 1e3:.1f} ms round trip ({answer.message})')
        print(f"{'#':>3} {'max step [rad]':>14} {'travel [rad]':>12} {'duration [s]':>12} "
              f"{'max err [mm]':>12} {'cost':>7}")
        for i, m in enumerate(answer.metrics, 1):
            print(f'{i:>3} {m.max_step:>14.3f} {m.travel:>12.3f} {m.duration:>12.2f} '
                  f'{1e3 * m.max_position_error:>12.4f} {m.cost:>7.3f}')
        ok &= answer.error_code in ANSWERED
    return ok


def run_demo(node: Node, client: 'SolveIKClient', goals: List[str]) -> bool:
    """Send the demo goals and print the answers; True if every request was answered.

    Service calls go through ``client`` (spun in its own thread, see
    :mod:`sik_ros.ros.client`); the topic goal through ``node``.
    """
    from sik_ros.kinematics.robots import load_robot
    robot = load_robot('panda')
    fk = {name: robot.fk(np.array(q)) for name, q in
          (('ready', READY), ('left', REACH_LEFT), ('low', REACH_LOW), ('right', REACH_RIGHT))}
    requests = [('position goal (left)', pose_request(fk['left'][0]))]
    if 'pose' in goals:
        requests.append(('pose goal (ready pose, gripper down)',
                         pose_request(fk['ready'][0], fk['ready'][1])))
    else:
        print('(the bundle has no pose model: the pose goal is skipped)')
    seeded = pose_request(fk['right'][0])
    seeded.seed.name = list(robot.joint_names)
    seeded.seed.position = [float(v) for v in READY]
    requests.append(('position goal (right) seeded with the ready posture', seeded))
    blocked = pose_request(fk['low'][0])
    shape, where = box((0.45, 0.0, 0.62), (0.12, 0.5, 0.12))
    blocked.obstacles, blocked.obstacle_poses = [shape], [where]
    requests.append(('position goal (low) with a box obstacle above the reach', blocked))
    ok = True
    for title, req in requests:
        t0 = time.perf_counter()
        answer = client.call(req)
        took = time.perf_counter() - t0
        p = req.target.pose.position
        title = f'{title} at ({p.x:.3f}, {p.y:.3f}, {p.z:.3f}) m'
        if answer is None:
            print(f'== {title}: no answer')
            ok = False
            continue
        print(format_answer(title, answer, took))
        ok &= answer.error_code in ANSWERED
    t0 = time.perf_counter()
    answer = topic_goal(node, fk['ready'][0])
    x, y, z = fk['ready'][0]
    title = f'topic ~/goal -> ~/solutions: position goal (ready) at ({x:.3f}, {y:.3f}, {z:.3f}) m'
    if answer is None:
        print(f'== {title}: no message on ~/solutions')
        return False
    print(format_answer(title, answer, time.perf_counter() - t0))
    ok &= answer.error_code in ANSWERED
    return path_demo(robot, 'pose' in goals) and ok


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of ``python -m sik_ros.ros.demo``."""
    parser = argparse.ArgumentParser(prog='python -m sik_ros.ros.demo', description=__doc__.split(
        '\n')[0])
    parser.add_argument('--model-dir', help='bundle directory (default: the bundled panda model)')
    parser.add_argument('--domain-id', type=int, help='ROS_DOMAIN_ID (default: a random one)')
    parser.add_argument('--startup-timeout', type=float, default=60.0,
                        help='wait this long for the node [s]')
    args = parser.parse_args(argv)
    env = ros_env(args.domain_id)
    print(f'starting sik_node (ROS_DOMAIN_ID={env["ROS_DOMAIN_ID"]}, bundle '
          f'{args.model_dir or "panda"}) ...', flush=True)
    proc = launch_node(args.model_dir, env=env)
    rclpy.init()
    ok = False
    try:
        node = rclpy.create_node('sik_demo')
        client = node.create_client(SolveIK, f'{NODE}/solve_ik')
        if not wait_for_service(node, client, proc, args.startup_timeout):
            print('sik_node did not come up' + (f' (exit code {proc.returncode})'
                                                if proc.poll() is not None else ''))
        else:
            with SolveIKClient(f'{NODE}/solve_ik', 'sik_demo_client') as fast:
                fast.wait_for_service(10.0)
                ok = run_demo(node, fast, bundle_goals(args.model_dir))
        node.destroy_node()
    except KeyboardInterrupt:
        print('interrupted')
    finally:
        code = stop_node(proc)
        rclpy.try_shutdown()
    if code != 0:
        print(f'sik_node exited with code {code}')
    print('demo ' + ('done' if ok and code == 0 else 'FAILED'))
    return 0 if ok and code == 0 else 1


if __name__ == '__main__':
    raise SystemExit(main())
