"""Benchmark of sik_node's ``~/solve_ik`` over loopback DDS: latency, throughput, memory.

Measures, for goals at FK of random configurations (position goals, pose goals, or both
alternating: ``--goals mixed``) and 16 ranked refined solutions:

- round-trip latency of sequential requests (p50, p99) [ms] from a :class:`SolveIKClient` (a
  background-spun client: ``spin_until_future_complete`` alone costs several ms per call), beside
  the solver's own time
  (``IKResult.elapsed``) for the same requests as the node reports it in each answer's message,
  and as measured in this process on the same targets, so the ROS overhead shows;
- throughput with several concurrent clients [requests/s];
- resident memory (VmRSS) growth of the node and its solver processes over all the requests
  sent [MB].

Usage: ``python bench/service.py [--quick] [--requests N] [--goals position|pose|mixed]
[--model-dir DIR] [--json PATH]``. Prints a table; the
figures are never asserted (see docs/benchmarks.md).
"""

import argparse
import os
import re
import subprocess
import threading
import time
from typing import List, Optional

import numpy as np
import rclpy
from rclpy.signals import SignalHandlerOptions
import torch

from sik_interfaces.srv import SolveIK
from sik_ros.robots import load_robot
from sik_ros.ros import client as ros_client, launch
from sik_ros.ros.client import SolveIKClient
from sik_ros.solver import SelectiveIK

from report import add_json_argument, write_json  # noqa: I100 (bench/report.py)

NUM_SOLUTIONS = 16
NODE_TIMEOUT = 0.05  # [s] config/panda.yaml
SERVICE = '/sik_node/solve_ik'
#: The solver time sik_node puts in its answers' message ('..., position goal, 4.2 ms').
SOLVER_MS = re.compile(r'goal, ([0-9.]+) ms')


def vm_rss_mb(pid: int) -> float:
    """Resident memory of a process and its children (the solver processes) [MB]."""
    total = 0.0
    with open(f'/proc/{pid}/status') as f:
        for line in f:
            if line.startswith('VmRSS:'):
                total += int(line.split()[1]) / 1024.0
    children = []
    for task in os.listdir(f'/proc/{pid}/task'):
        with open(f'/proc/{pid}/task/{task}/children') as f:
            children += [int(c) for c in f.read().split()]
    return total + sum(vm_rss_mb(c) for c in children)


def targets(count: int, seed: int = 0, kinds: str = 'position') -> List[tuple]:
    """Reachable goals: (position (3,) [m], quaternion (4,) or None) of random configurations.

    ``kinds``: ``position``, ``pose``, or ``mixed`` (pose goals at odd places).
    """
    robot = load_robot('panda')
    q = np.random.default_rng(seed).uniform(robot.lower, robot.upper, (count, robot.dof))
    pos, quat = robot.fk_batch(q)
    pose = [kinds == 'pose' or (kinds == 'mixed' and i % 2 == 1) for i in range(count)]
    return [(pos[i], quat[i] if pose[i] else None) for i in range(count)]


def percentiles(seconds) -> str:
    """Format 'p50 / p99' in milliseconds (NaNs ignored)."""
    p50, p99 = np.nanpercentile(np.asarray(seconds, dtype=float) * 1e3, [50, 99])
    return f'{p50:.2f} / {p99:.2f}'


def sequential(client: SolveIKClient, goals: List[tuple]):
    """Time one request per goal, one at a time.

    Returns:
        round trips [s], the node's solver time of each (from the answer's message) [s], and
        the answer codes (None: no answer).
    """
    times, inside, codes = [], [], []
    for p, quat in goals:
        req = ros_client.pose_request(p, quat, max_solutions=NUM_SOLUTIONS)
        t0 = time.perf_counter()
        answer = client.call(req)
        times.append(time.perf_counter() - t0)
        codes.append(None if answer is None else answer.error_code)
        took = None if answer is None else SOLVER_MS.search(answer.message)
        inside.append(float(took.group(1)) * 1e-3 if took else np.nan)
    return times, inside, codes


def concurrent(goals: List[tuple], clients: int, duration: float):
    """Count requests answered to ``clients`` threads calling back to back for ``duration`` [s]."""
    counts = [0] * clients
    start = threading.Barrier(clients + 1)
    stop = threading.Event()

    def run(k):
        with SolveIKClient(SERVICE, f'sik_bench_client_{k}') as cli:
            cli.wait_for_service(10.0)
            start.wait()
            i = k
            while not stop.is_set():
                p, quat = goals[i % len(goals)]
                answer = cli.call(ros_client.pose_request(p, quat, max_solutions=NUM_SOLUTIONS))
                counts[k] += answer is not None
                i += clients

    threads = [threading.Thread(target=run, args=(k,)) for k in range(clients)]
    for t in threads:
        t.start()
    start.wait()
    t0 = time.perf_counter()
    time.sleep(duration)
    stop.set()
    for t in threads:
        t.join()
    return sum(counts), time.perf_counter() - t0


def in_process(bundle: str, goals: List[tuple]) -> List[float]:
    """Time the solver alone [s] on the same goals, as the node runs it (one thread)."""
    torch.set_num_threads(1)
    ik = SelectiveIK.load(bundle).with_config(position_tolerance=1e-4,
                                              orientation_tolerance=1e-3)
    for p, quat in goals[:10]:
        ik.solve(p, quat, num_solutions=NUM_SOLUTIONS, timeout=NODE_TIMEOUT)
    return [ik.solve(p, quat, num_solutions=NUM_SOLUTIONS, timeout=NODE_TIMEOUT).elapsed
            for p, quat in goals]


def figures(args: argparse.Namespace, n: int, rtt, inside, solver, answered: int,
            wall: float, rss0: float, rss1: float, ok: int, goals: List[tuple]) -> dict:
    """The printed figures as a dict for ``--json`` (times [ms], memory [MB])."""
    def pct(seconds) -> dict:
        p50, p99 = np.nanpercentile(np.asarray(seconds, dtype=float) * 1e3, [50, 99])
        return {'p50_ms': float(p50), 'p99_ms': float(p99)}

    rtt_a, inside_a = np.asarray(rtt), np.asarray(inside)
    out = {'goals': args.goals, 'requests': n, 'clients': args.clients,
           'duration_s': wall, 'params': args.param, 'solutions': NUM_SOLUTIONS,
           'round_trip': pct(rtt_a), 'solver_in_node': pct(inside_a),
           'overhead': pct(rtt_a - inside_a), 'solver_alone': pct(solver),
           'throughput_rps': answered / wall, 'rss_start_mb': rss0, 'rss_end_mb': rss1,
           'rss_growth_mb': rss1 - rss0, 'requests_total': n + answered,
           'success': ok / len(rtt)}
    if args.goals == 'mixed':
        pose = np.array([quat is not None for _, quat in goals])
        out['round_trip_position'] = pct(rtt_a[~pose])
        out['round_trip_pose'] = pct(rtt_a[pose])
    return out


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--quick', action='store_true',
                        help='a short run: 200 requests, 3 s of concurrent clients')
    parser.add_argument('--requests', type=int,
                        help='sequential requests for latency and memory (default 10000)')
    parser.add_argument('--clients', type=int, default=4, help='concurrent clients')
    parser.add_argument('--duration', type=float, help='concurrent phase [s] (default 20)')
    parser.add_argument('--goals', choices=('position', 'pose', 'mixed'), default='position',
                        help='goal kinds of the requests (mixed: alternating)')
    parser.add_argument('--model-dir', help='bundle directory (default: the bundled panda)')
    parser.add_argument('-p', '--param', action='append', default=[],
                        help='a node parameter override name:=value (repeatable)')
    add_json_argument(parser)
    args = parser.parse_args(argv)
    n = args.requests or (200 if args.quick else 10_000)
    duration = args.duration or (3.0 if args.quick else 20.0)
    bundle = args.model_dir or 'panda'
    goals = targets(n, kinds=args.goals)

    env = launch.ros_env()
    proc = launch.launch_node(args.model_dir, args.param, env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.STDOUT)
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = rclpy.create_node('sik_bench_probe')
        probe = node.create_client(SolveIK, SERVICE)
        up = launch.wait_for_service(node, probe, proc, 90.0)
        node.destroy_node()
        if not up:
            print(f'sik_node did not come up (exit code {proc.poll()})')
            return 1
        with SolveIKClient(SERVICE, 'sik_bench') as client:
            client.wait_for_service(10.0)
            sequential(client, targets(20, seed=1, kinds=args.goals))  # warm-up
            rss0 = vm_rss_mb(proc.pid)
            rtt, inside, codes = sequential(client, goals)
        answered, wall = concurrent(goals, args.clients, duration)
        rss1 = vm_rss_mb(proc.pid)
    finally:
        launch.stop_node(proc)
        rclpy.try_shutdown()
    solver = in_process(bundle, goals)
    ok = sum(c == SolveIK.Response.SUCCESS for c in codes)
    rows = [
        ('round trip p50 / p99 [ms]', percentiles(rtt), '<= 5 / <= 20'),
        ('solver in the node p50 / p99 [ms]', percentiles(inside), ''),
        ('ROS overhead (round trip - solver) p50 / p99 [ms]',
         percentiles(np.asarray(rtt) - np.asarray(inside)), ''),
        ('solver alone p50 / p99 [ms] (this process)', percentiles(solver), ''),
        (f'throughput, {args.clients} clients [req/s]', f'{answered / wall:.0f}', '>= 200'),
        (f'node RSS growth over {n + answered} requests [MB]',
         f'{rss1 - rss0:+.1f} ({rss0:.0f} -> {rss1:.0f})', '< 10 over 10,000'),
        ('SUCCESS answers (sequential)', f'{ok}/{len(codes)}', ''),
    ]
    if args.goals == 'mixed':
        pose = np.array([quat is not None for _, quat in goals])
        rtt_a = np.asarray(rtt)
        rows[1:1] = [('  position goals: round trip p50 / p99 [ms]', percentiles(rtt_a[~pose]),
                      ''),
                     ('  pose goals: round trip p50 / p99 [ms]', percentiles(rtt_a[pose]), '')]
    print(f'sik_node ~/solve_ik over loopback DDS: bundle {bundle}, {args.goals} goals, '
          f'{NUM_SOLUTIONS} ranked refined solutions, node timeout {NODE_TIMEOUT * 1e3:.0f} ms'
          + (f', parameters {" ".join(args.param)}' if args.param else '')
          + (' (quick run)' if args.quick else ''))
    write_json(args.json, 'service', figures(args, n, rtt, inside, solver, answered, wall,
                                             rss0, rss1, ok, goals))
    width = max(len(r[0]) for r in rows)
    print(f"| {'metric':<{width}} | {'measured':>22} | {'target':>16} |")
    print(f"|{'-' * (width + 2)}|{'-' * 24}|{'-' * 18}|")
    for name, value, goal in rows:
        print(f'| {name:<{width}} | {value:>22} | {goal:>16} |')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
