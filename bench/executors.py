"""Three rclpy executors serving what sik_node serves: a slow subscription and a service.

A server process spins one node with a ``PoseStamped`` subscription whose callback works for
``--work`` ms (NumPy, as a solve does, holding the GIL part of the time) and an empty
``std_srvs/Trigger`` service, both in a reentrant callback group, with one of

- ``multi``: rclpy's ``MultiThreadedExecutor`` with 4 threads (sik_node's executor until 0.5.0),
- ``slotted``: :class:`sik_ros.ros.executor.SlottedExecutor` with 4 threads (sik_node's),
- ``events``: ``rclpy.experimental.EventsExecutor`` (one thread).

For each, this process measures: the server's processor time while idle [% of a core]; the
service's round trip alone (p50, p99) [ms]; a 100 Hz stream of goals for ``--duration`` s:
callbacks run per second and their delay after publication (p50, p99) [ms], and how many
times the executor handed a callback to its threads per goal (``multi`` resubmits tasks that
wait for a thread); and the service's round trip during the stream.

Usage: ``python bench/executors.py [--duration 5] [--work 2] [--json PATH]``. Prints a table;
the figures are never asserted (see docs/benchmarks.md, "The executor").
"""

import argparse
import subprocess
import sys
import threading
import time
from typing import Dict, List, Optional

from geometry_msgs.msg import PoseStamped
import numpy as np
import rclpy
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from sik_ros.ros import launch
from sik_ros.ros.client import SolveIKClient

from report import add_json_argument, write_json  # noqa: I100 (bench/report.py)
from service import cpu_seconds  # noqa: I100 (bench/service.py)

KINDS = ('multi', 'slotted', 'events')
NAME = 'sik_bench_executor'


def serve(kind: str, work_ms: float) -> None:
    """The server process: spin a node with the subscription and the service until killed."""
    from rclpy.callback_groups import ReentrantCallbackGroup
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.experimental import EventsExecutor

    from sik_ros.ros.executor import SlottedExecutor
    rclpy.init()
    node = rclpy.create_node(NAME)
    group = ReentrantCallbackGroup()
    report = node.create_publisher(Float64MultiArray, f'/{NAME}/done', 1000)
    submits = [0]
    a = np.random.default_rng(0).normal(size=(60, 60))

    def on_goal(msg: PoseStamped) -> None:
        end = time.perf_counter() + work_ms * 1e-3
        while time.perf_counter() < end:
            a @ a  # NumPy releases the GIL inside, Python holds it between
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        report.publish(Float64MultiArray(data=[stamp, time.time(), float(submits[0])]))

    node.create_subscription(PoseStamped, f'/{NAME}/goal', on_goal, 100, callback_group=group)
    node.create_service(Trigger, f'/{NAME}/trigger',
                        lambda req, res: Trigger.Response(success=True), callback_group=group)
    if kind == 'multi':
        executor = MultiThreadedExecutor(num_threads=4)
        pool_submit = executor._executor.submit  # counted: the executor's hand-overs

        def counted(*args, **kwargs):
            submits[0] += 1
            return pool_submit(*args, **kwargs)
        executor._executor.submit = counted
    elif kind == 'slotted':
        executor = SlottedExecutor(4)
        pool_submit = executor._pool.submit

        def counted(*args, **kwargs):
            submits[0] += 1
            return pool_submit(*args, **kwargs)
        executor._pool.submit = counted
    else:
        executor = EventsExecutor()
    executor.add_node(node)
    try:
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    except BaseException:
        pass


def round_trips(client: SolveIKClient, count: int) -> List[float]:
    """Round trips of ``count`` sequential Trigger calls [ms]."""
    out = []
    for _ in range(count):
        t0 = time.perf_counter()
        if client.call(Trigger.Request(), timeout=5.0) is not None:
            out.append((time.perf_counter() - t0) * 1e3)
    return out


def measure(kind: str, args, env: Dict[str, str]) -> Dict:
    """Start a server with one executor and measure it."""
    proc = subprocess.Popen([sys.executable, __file__, '--serve', kind, '--work',
                             str(args.work)], env=env)
    done: List[tuple] = []
    try:
        with SolveIKClient(f'/{NAME}/trigger', node_name=f'exec_bench_{kind}',
                           srv_type=Trigger) as client:
            if not client.wait_for_service(30.0):
                raise SystemExit(f'{kind}: the server did not come up')
            node = client.node
            pub = node.create_publisher(PoseStamped, f'/{NAME}/goal', 100)
            node.create_subscription(Float64MultiArray, f'/{NAME}/done',
                                     lambda m: done.append((time.time(), *m.data)), 1000)
            time.sleep(1.0)
            round_trips(client, 20)  # warm-up
            cpu0 = cpu_seconds(proc.pid)
            time.sleep(2.0)
            idle_cpu = (cpu_seconds(proc.pid) - cpu0) / 2.0 * 100
            alone = round_trips(client, 200)
            during: List[float] = []
            stop = threading.Event()

            def call_loop():
                while not stop.is_set():
                    during.extend(round_trips(client, 1))
                    time.sleep(0.01)
            caller = threading.Thread(target=call_loop)
            sent, t0 = int(args.duration * 100), time.monotonic()
            caller.start()
            for i in range(sent):
                while time.monotonic() < t0 + i / 100:
                    time.sleep(0.0005)
                msg = PoseStamped()
                now = time.time_ns()
                msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(now, 1_000_000_000)
                pub.publish(msg)
            time.sleep(1.0)
            stop.set()
            caller.join()
            delays = [(d[2] - d[1]) * 1e3 for d in done]
            submits = done[-1][3] if done else float('nan')
    finally:
        proc.terminate()
        proc.wait(10)
    return {'executor': kind, 'idle_cpu': idle_cpu,
            'service_p50': float(np.median(alone)), 'service_p99': float(np.percentile(alone, 99)),
            'stream_sent': sent, 'stream_done': len(done),
            'stream_delay_p50': float(np.median(delays)) if delays else float('nan'),
            'stream_delay_p99': float(np.percentile(delays, 99)) if delays else float('nan'),
            'handovers_per_goal': submits / max(len(done), 1),
            'service_during_p50': float(np.median(during)) if during else float('nan')}


def main(argv: Optional[List[str]] = None) -> int:
    """Run the comparison (or, with ``--serve``, be the server)."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--serve', choices=KINDS, help=argparse.SUPPRESS)
    parser.add_argument('--work', type=float, default=2.0, help='callback work [ms]')
    parser.add_argument('--duration', type=float, default=5.0, help='stream length [s]')
    parser.add_argument('--executors', nargs='+', default=list(KINDS), choices=KINDS)
    add_json_argument(parser)
    args = parser.parse_args(argv)
    if args.serve:
        serve(args.serve, args.work)
        return 0
    env = launch.ros_env()
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    rows = []
    try:
        for kind in args.executors:
            row = measure(kind, args, env)
            rows.append(row)
            print(f'{kind:8s} idle CPU {row["idle_cpu"]:5.1f} %, service p50/p99 '
                  f'{row["service_p50"]:.2f}/{row["service_p99"]:.2f} ms; 100 Hz stream: '
                  f'{row["stream_done"]}/{row["stream_sent"]} callbacks, delay p50/p99 '
                  f'{row["stream_delay_p50"]:.1f}/{row["stream_delay_p99"]:.1f} ms, '
                  f'{row["handovers_per_goal"]:.1f} hand-overs per goal, service meanwhile '
                  f'p50 {row["service_during_p50"]:.2f} ms', flush=True)
    finally:
        rclpy.try_shutdown()
    if args.json:
        write_json(args.json, 'executors',
                   {'work_ms': args.work, 'duration': args.duration, 'rows': rows})
    return 0


if __name__ == '__main__':
    sys.exit(main())
