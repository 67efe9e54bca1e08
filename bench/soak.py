"""Soak sik_node: many concurrent clients, mixed requests and parameter churn; lost answers, RSS.

Starts the node on the bundled Panda model, then ``--clients`` threads (each with its own
:class:`~sik_ros.ros.client.SolveIKClient`, so each is a new DDS participant) send
``--requests`` requests in all: position and pose goals, some with obstacles, some with a seed;
meanwhile ``position_tolerance`` is changed every ``--churn`` requests (a new value each time).
Prints answered / lost, the codes, round-trip p50 / p99 [ms] and the node's RSS (with its solver
processes) after the node's warm-up, once every client is connected and answered once (each
client is a new DDS participant: its discovery data is the node's too), and at the end.

    python bench/soak.py --requests 10000 --clients 16 [--json PATH]
"""

import argparse
from collections import Counter
import os
import threading
import time

import numpy as np
from rcl_interfaces.msg import Parameter as ParameterMsg, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
import rclpy
from shape_msgs.msg import SolidPrimitive

from sik_ros.kinematics.robots import load_robot
from sik_ros.ros import client as ros_client, launch
from sik_ros.ros.client import SolveIKClient

from report import add_json_argument, write_json  # noqa: I100 (bench/report.py)


def rss_mb(pid: int) -> float:
    """Resident memory of a process and its children [MB]."""
    total = 0
    pids = [pid]
    for task in os.listdir(f'/proc/{pid}/task'):
        with open(f'/proc/{pid}/task/{task}/children') as f:
            pids += [int(c) for c in f.read().split()]
    for p in pids:
        try:
            with open(f'/proc/{p}/status') as f:
                for line in f:
                    if line.startswith('VmRSS:'):
                        total += int(line.split()[1])
        except FileNotFoundError:
            pass
    return total / 1024


def make_request(rng, robot, timeout):
    """A random request: position or pose goal, maybe obstacles, maybe a seed."""
    q = rng.uniform(robot.lower, robot.upper)
    p, quat = robot.fk(q)
    req = ros_client.pose_request(p, quat if rng.random() < 0.5 else None, 16)
    if rng.random() < 0.2:
        for _ in range(int(rng.integers(1, 8))):
            req.obstacles.append(SolidPrimitive(type=SolidPrimitive.SPHERE, dimensions=[0.05]))
            pose = ros_client.pose_request(rng.uniform(-0.8, 0.8, 3)).target.pose
            req.obstacle_poses.append(pose)
    if rng.random() < 0.3:
        req.seed.name = list(robot.joint_names)
        req.seed.position = rng.uniform(robot.lower, robot.upper).tolist()
    req.timeout.sec, req.timeout.nanosec = int(timeout), int((timeout % 1) * 1e9)
    return req


def main() -> None:
    """Run the soak and print its figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--requests', type=int, default=10000)
    parser.add_argument('--clients', type=int, default=16)
    parser.add_argument('--churn', type=int, default=50, help='requests per parameter change')
    parser.add_argument('--timeout', type=float, default=0.5, help='request timeout [s]')
    parser.add_argument('--processes', type=int, default=0, help='solver_processes')
    parser.add_argument('--rounds', type=int, default=1,
                        help='rounds of --requests on the same node (RSS after each)')
    add_json_argument(parser)
    args = parser.parse_args()
    env = launch.ros_env()
    proc = launch.launch_node(None, [f'solver_processes:={args.processes}'], env=env)
    rclpy.init()
    robot = load_robot('panda')
    admin = SolveIKClient(node_name='soak_admin')
    params = admin.node.create_client(SetParameters, '/sik_node/set_parameters')
    assert admin.wait_for_service(120.0), 'sik_node did not come up'
    params.wait_for_service(10.0)
    for _ in range(20):  # warm up
        admin.call(make_request(np.random.default_rng(0), robot, args.timeout), 10.0)
    rss0 = rss_mb(proc.pid)
    codes, times, lost = Counter(), [], [0]
    counter, lock = [0], threading.Lock()
    connected = threading.Barrier(args.clients + 1)

    def client_loop(k: int) -> None:
        rng = np.random.default_rng(100 + k)
        client = SolveIKClient(node_name=f'soak_{k}')
        client.wait_for_service(30.0)
        client.call(make_request(rng, robot, args.timeout), args.timeout + 5.0)  # not counted
        connected.wait()  # every client matched and answered once: RSS measured here
        connected.wait()
        while True:
            with lock:
                if counter[0] >= args.requests:
                    break
                counter[0] += 1
                n = counter[0]
            if n % args.churn == 0:
                value = ParameterValue(type=ParameterType.PARAMETER_DOUBLE,
                                       double_value=1e-4 * (1 + (n // args.churn) % 500 / 1000))
                params.call_async(SetParameters.Request(parameters=[
                    ParameterMsg(name='position_tolerance', value=value)]))
            t0 = time.perf_counter()
            answer = client.call(make_request(rng, robot, args.timeout), args.timeout + 5.0)
            with lock:
                if answer is None:
                    lost[0] += 1
                else:
                    codes[answer.error_code] += 1
                    times.append(time.perf_counter() - t0)
        client.close()

    print(f'# bench/soak.py: {args.requests} requests from {args.clients} clients per round, '
          f'{args.rounds} rounds on one node, solver_processes {args.processes}, timeout '
          f'{args.timeout} s, a parameter change every {args.churn}', flush=True)
    print(f'node RSS {rss0:.1f} MB after the warm-up', flush=True)
    rounds = []
    for round_ in range(args.rounds):
        codes.clear()
        times.clear()
        lost[0] = 0
        counter[0] = 0
        t0 = time.perf_counter()
        threads = [threading.Thread(target=client_loop, args=(k + 100 * round_,))
                   for k in range(args.clients)]
        for t in threads:
            t.start()
        connected.wait()
        rss_c = rss_mb(proc.pid)
        connected.wait()
        for t in threads:
            t.join()
        wall = time.perf_counter() - t0
        time.sleep(1.0)
        rss1 = rss_mb(proc.pid)
        ms = 1e3 * np.array(times)
        rounds.append({'answered': len(times), 'lost': lost[0],
                       'codes': {str(k): v for k, v in codes.items()}, 'wall_s': wall,
                       'rate_rps': len(times) / wall, 'p50_ms': float(np.percentile(ms, 50)),
                       'p99_ms': float(np.percentile(ms, 99)), 'max_ms': float(ms.max()),
                       'rss_mb': rss1, 'rss_growth_mb': rss1 - rss0,
                       'rss_growth_connected_mb': rss1 - rss_c})
        print(f'round {round_ + 1}: answered {len(times)}, lost {lost[0]}, codes {dict(codes)}, '
              f'{wall:.0f} s ({len(times) / wall:.0f} req/s); round trip p50 '
              f'{np.percentile(ms, 50):.1f} ms, p99 {np.percentile(ms, 99):.1f} ms, max '
              f'{ms.max():.1f} ms; node RSS {rss1:.1f} MB ({rss1 - rss0:+.1f} MB since the '
              f'warm-up, {rss1 - rss_c:+.1f} MB since the {args.clients} clients were connected '
              f'and answered once, at {rss_c:.1f} MB)', flush=True)
    admin.close()
    rclpy.shutdown()
    launch.stop_node(proc)
    write_json(args.json, 'soak', {'requests': args.requests, 'clients': args.clients,
                                   'churn': args.churn, 'timeout_s': args.timeout,
                                   'processes': args.processes, 'rss_start_mb': rss0,
                                   'rounds': rounds})


if __name__ == '__main__':
    main()
