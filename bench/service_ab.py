"""Paired A/B of ``sik_node``'s ``~/solve_ik`` round trip between checkouts, request by request.

Each checkout's node runs as a process of its own (its ``sik_ros`` first on the path, its own
``config/panda.yaml``, renamed ``sik_node_<NAME>`` so that both share one ROS graph); one
client calls them in turn with the same request, the order flipping every request, so the
machine's drift falls on both alike. Goals are FK of random configurations (position and pose
goals alternating), 16 solutions each. Prints per checkout the round trip p50 / p99 and the
median of the per-request ratios to the first checkout.

    python bench/service_ab.py old=/path/to/checkout new=. --requests 400
    python bench/service_ab.py old=@v0.4.0 new=. --requests 400   # @REV: a worktree of REV

The figures are never asserted (see docs/benchmarks.md).
"""

import argparse
from contextlib import ExitStack
from pathlib import Path
import subprocess
import sys
import tempfile
import time
from typing import Dict, List, Optional

import numpy as np
import rclpy
from rclpy.signals import SignalHandlerOptions

from sik_ros.kinematics.robots import load_robot
from sik_ros.ros import launch
from sik_ros.ros.client import pose_request, SolveIKClient

from report import add_json_argument, git_commit, write_json  # noqa: I100 (bench/report.py)


def start(name: str, checkout: Path, env: Dict[str, str]) -> subprocess.Popen:
    """``checkout``'s node, named ``sik_node_<name>``."""
    cmd = [sys.executable, '-m', 'sik_ros.ros.run', '--ros-args', '--params-file',
           str(checkout / 'config' / 'panda.yaml'), '-r', f'__node:=sik_node_{name}']
    return subprocess.Popen(cmd, env=dict(env, PYTHONPATH=str(checkout)),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def checkout_path(spec: str, stack: ExitStack) -> Path:
    """A checkout's folder: ``PATH``, or for ``@REV`` a temporary worktree of this repository."""
    if not spec.startswith('@'):
        return Path(spec).resolve()
    repo = Path(__file__).resolve().parents[1]
    folder = Path(stack.enter_context(tempfile.TemporaryDirectory())) / 'checkout'
    subprocess.run(['git', 'worktree', 'add', '--detach', str(folder), spec[1:]], cwd=repo,
                   check=True, capture_output=True)
    stack.callback(subprocess.run, ['git', 'worktree', 'remove', '--force', str(folder)],
                   cwd=repo, capture_output=True)
    return folder


def main(argv: Optional[List[str]] = None) -> int:
    """Run the A/B between two checkouts."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('checkouts', nargs=2, metavar='NAME=PATH')
    parser.add_argument('--requests', type=int, default=400)
    add_json_argument(parser)
    args = parser.parse_args(argv)
    with ExitStack() as stack:
        names = [c.split('=', 1)[0] for c in args.checkouts]
        paths = [checkout_path(c.split('=', 1)[1], stack) for c in args.checkouts]
        return run(args, names, paths)


def run(args, names: List[str], paths: List[Path]) -> int:
    """Call both nodes in turn; print and optionally write the figures."""
    env = launch.ros_env()
    procs = [start(n, p, env) for n, p in zip(names, paths)]
    robot = load_robot('panda')
    rng = np.random.default_rng(0)
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    times: Dict[str, List[float]] = {n: [] for n in names}
    try:
        clients = [SolveIKClient(f'/sik_node_{n}/solve_ik', node_name=f'ab_{n}') for n in names]
        for c, p in zip(clients, procs):
            if not launch.wait_for_service(c.node, c.client, p, 180.0):
                raise SystemExit('a node did not come up')
        for i in range(args.requests + 20):
            q = rng.uniform(robot.lower, robot.upper)
            pos, quat = robot.fk(q)
            request = pose_request(pos, quat if i % 2 else None, 16)
            order = [0, 1] if i % 2 == (i // 2) % 2 else [1, 0]
            for k in order:
                t0 = time.perf_counter()
                answer = clients[k].call(request, timeout=10.0)
                if answer is not None and i >= 20:  # the first 20: warm-up
                    times[names[k]].append((time.perf_counter() - t0) * 1e3)
        for c in clients:
            c.close()
    finally:
        rclpy.try_shutdown()
        for p in procs:
            launch.stop_node(p)
    a, b = (np.array(times[n]) for n in names)
    n = min(len(a), len(b))
    ratio = float(np.median(b[:n] / a[:n]))
    rows = {name: {'p50_ms': float(np.median(t)), 'p99_ms': float(np.percentile(t, 99)),
                   'requests': len(t)} for name, t in times.items()}
    for name in names:
        r = rows[name]
        print(f'{name}: round trip p50 {r["p50_ms"]:.2f} ms, p99 {r["p99_ms"]:.2f} ms '
              f'({r["requests"]} requests)')
    print(f'{names[1]} / {names[0]}: median of the paired ratios {ratio:.3f}')
    if args.json:
        write_json(args.json, 'service_ab', {'rows': rows, 'ratio': ratio, 'names': names},
                   checkouts={n: git_commit(str(p)) for n, p in zip(names, paths)})
    return 0


if __name__ == '__main__':
    sys.exit(main())
