"""How the client is written changes sik_node's measured round trip: three client loops, one node.

Starts the node and sends the same position goals (16 solutions) with

- ``spin_call`` (``rclpy.spin_until_future_complete`` on the node, as the rclpy tutorials do),
- a ``SingleThreadedExecutor`` loop (``executor.spin_until_future_complete``),
- :class:`sik_ros.ros.client.SolveIKClient` (an executor spun in a background thread, each call
  waiting on a ``threading.Event``),

and prints, per loop, round trip, the node's own solver time and their difference (p50 / p99),
and the client process's CPU time per request. See docs/benchmarks.md.

    python bench/service_probe.py [--requests 200] [--json PATH]
"""

import argparse
import re
import subprocess
import time

import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions

from sik_interfaces.srv import SolveIK
from sik_ros.kinematics.robots import load_robot
from sik_ros.ros import client as ros_client, launch
from sik_ros.ros.client import SolveIKClient

from report import add_json_argument, write_json  # noqa: I100 (bench/report.py)

SOLVER_MS = re.compile(r'goal, ([0-9.]+) ms')


def spin_call(node, client, request, timeout: float = 10.0):
    """A call as the rclpy tutorials make it: ``spin_until_future_complete`` on the node."""
    future = client.call_async(request)
    rclpy.spin_until_future_complete(node, future, timeout_sec=timeout)
    if not future.done():
        client.remove_pending_request(future)
        return None
    return future.result()


def main() -> None:
    """Entry point."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--requests', type=int, default=200)
    add_json_argument(parser)
    args = parser.parse_args()
    robot = load_robot('panda')
    q = np.random.default_rng(0).uniform(robot.lower, robot.upper, (args.requests, robot.dof))
    goals = robot.fk_batch(q)[0]
    env = launch.ros_env()
    proc = launch.launch_node(None, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('sik_probe')
    client = node.create_client(SolveIK, '/sik_node/solve_ik')
    loops = []
    try:
        if not launch.wait_for_service(node, client, proc, 90.0):
            raise SystemExit('sik_node did not come up')
        for mode in ('spin_call', 'executor loop', 'SolveIKClient'):
            executor, fast = None, None
            if mode == 'executor loop':
                executor = SingleThreadedExecutor()
                executor.add_node(node)
            elif mode == 'SolveIKClient':
                fast = SolveIKClient(node_name='sik_probe_fast')
                fast.wait_for_service(10.0)
            rtt, inside = [], []
            cpu0 = time.process_time()
            for p in goals:
                req = ros_client.pose_request(p, max_solutions=16)
                t0 = time.perf_counter()
                if executor:
                    future = client.call_async(req)
                    executor.spin_until_future_complete(future, timeout_sec=10.0)
                    answer = future.result()
                elif fast:
                    answer = fast.call(req)
                else:
                    answer = spin_call(node, client, req)
                rtt.append(time.perf_counter() - t0)
                took = SOLVER_MS.search(answer.message)
                inside.append(float(took.group(1)) * 1e-3 if took else np.nan)
            cpu = (time.process_time() - cpu0) / len(goals) * 1e3
            if executor:
                executor.remove_node(node)
                executor.shutdown()
            if fast:
                fast.close()
            rtt_ms, in_ms = np.array(rtt) * 1e3, np.array(inside) * 1e3
            loops.append({'loop': mode, 'round_trip_p50_ms': float(np.median(rtt_ms)),
                          'round_trip_p99_ms': float(np.percentile(rtt_ms, 99)),
                          'solver_p50_ms': float(np.nanmedian(in_ms)),
                          'overhead_p50_ms': float(np.nanmedian(rtt_ms - in_ms)),
                          'client_cpu_ms': cpu})
            print(f'{mode:>14}: round trip p50 {np.median(rtt_ms):.2f} / p99 '
                  f'{np.percentile(rtt_ms, 99):.2f} ms, solver p50 {np.nanmedian(in_ms):.2f} ms,'
                  f' overhead p50 {np.nanmedian(rtt_ms - in_ms):.2f} ms, client CPU '
                  f'{cpu:.2f} ms/request')
    finally:
        node.destroy_node()
        launch.stop_node(proc)
        rclpy.try_shutdown()
    write_json(args.json, 'service_probe', {'requests': args.requests, 'loops': loops})


if __name__ == '__main__':
    main()
