"""Benchmark of sik_node's ``~/goal`` stream, measured on the wire by a client like a servo's.

For each goal kind (pose, position) a node serves the bundled model with
``use_joint_states:=true`` (and ``goal_use_orientation`` for pose goals); a client
(:class:`~sik_ros.ros.stream_client.GoalStreamClient`) streams goals along a smooth 10 cm circle
(one turn in 4 s) at each rate for ``--duration`` seconds, with a simulated arm that follows the
first solution of each answer on ``joint_states`` (and starts each stream at the circle's
start). Per stream: goals answered, the latency of a
goal's own answer, the staleness of the newest answer (from each goal until an answer to it or
to a newer goal arrived: p50, p99), the last answer's delay after the last goal, answers out of
order, answers that carry their goal's stamp, codes (TIMEOUT, JOINT_JUMP), posture flips
(consecutive answers more than 0.3 rad apart in a joint), every answer checked by the
project's forward kinematics (``Robot.fk``, tested against Pinocchio's), replaced goals, and
the node's processor time [% of one core]. Then, for each kind, ``~/solve_ik`` round trips
alone and during a 1 kHz stream (16 solutions, p50).

Usage: ``python bench/stream.py [--rates 100 500 1000] [--duration 10] [--goals pose position]
[--busy] [--model-dir DIR] [--json PATH]``. ``--busy`` keeps one core busy with another process
during the streams. Prints a table; the figures are never asserted (see docs/benchmarks.md).
"""

import argparse
import multiprocessing
import subprocess
import sys
import threading
import time
from typing import Dict, List, Optional

import numpy as np
import rclpy
from rclpy.signals import SignalHandlerOptions

from sik_ros.ros import launch
from sik_ros.ros.client import pose_request, SolveIKClient
from sik_ros.ros.stream_client import circle_goals, GoalStreamClient, stream_report
from sik_ros.solver import SelectiveIK

from report import add_json_argument, write_json  # noqa: I100 (bench/report.py)
from service import cpu_seconds  # noqa: I100 (bench/service.py)

RADIUS = 0.10      # [m]
TURN = 4.0         # time of one turn of the circle [s]
SERVICE_CALLS = 40


def _spin_forever() -> None:
    while True:
        pass


def circle(robot, rate: float, duration: float):
    """Goals along the circle through the tip at the middle of the joint ranges."""
    q_mid = (robot.lower + robot.upper) / 2
    p, quat = robot.fk(q_mid)
    return circle_goals(p, RADIUS, int(rate * duration), TURN, rate), quat


def service_p50(client: SolveIKClient, goals: np.ndarray, quat, pose: bool) -> float:
    """Median ``~/solve_ik`` round trip over the goals [ms]."""
    times = []
    for p in goals[:SERVICE_CALLS]:
        req = pose_request(p, quat if pose else None, 16)
        t0 = time.perf_counter()
        answer = client.call(req, timeout=10.0)
        if answer is not None:
            times.append((time.perf_counter() - t0) * 1e3)
    return float(np.median(times)) if times else float('nan')


def run_kind(kind: str, args, robot, env: Dict[str, str]) -> List[Dict]:
    """Start a node for one goal kind and measure every rate; its rows."""
    pose = kind == 'pose'
    params = ['use_joint_states:=true', f'goal_use_orientation:={str(pose).lower()}',
              'publish_markers:=false'] + list(args.param)
    proc = launch.launch_node(args.model_dir, params, env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    rows = []
    try:
        with SolveIKClient(node_name='sik_stream_bench_srv') as service, \
                GoalStreamClient(robot.joint_names, follow=True,
                                 frame_id=robot.base_frame) as client:
            if not (launch.wait_for_service(service.node, service.client, proc, 120.0)
                    and client.wait_for_node(20.0)):
                raise SystemExit('sik_node did not come up')
            warm, quat = circle(robot, 100, 1.0)
            client.run(warm, 100, quat if pose else None)  # warm-up, not measured
            q_mid = (robot.lower + robot.upper) / 2
            for rate in args.rates:
                goals, quat = circle(robot, rate, args.duration)
                client.publish_state(q_mid)  # the arm back at the circle's start
                time.sleep(0.2)
                cpu0, t0 = cpu_seconds(proc.pid), time.monotonic()
                record = client.run(goals, rate, quat if pose else None)
                cpu = (cpu_seconds(proc.pid) - cpu0) / (time.monotonic() - t0) * 100
                row = stream_report(record, fk=robot.fk)
                row.update(kind=kind, node_cpu=cpu)
                rows.append(row)
                print(f'{kind} {rate:g} Hz: {format_row(row)}', flush=True)
            alone = service_p50(service, goals, quat, pose)
            goals, quat = circle(robot, 1000, 3.0)
            client.publish_state(q_mid)
            time.sleep(0.2)
            during: List[float] = []
            thread = threading.Thread(target=lambda: during.append(
                service_p50(service, goals, quat, pose)))
            thread.start()
            client.run(goals, 1000, quat if pose else None)
            thread.join()
            rows.append({'kind': kind, 'service_alone_p50': alone,
                         'service_during_1khz_p50': during[0] if during else float('nan')})
            print(f'{kind}: ~/solve_ik p50 {alone:.2f} ms alone, '
                  f'{rows[-1]["service_during_1khz_p50"]:.2f} ms during a 1 kHz stream',
                  flush=True)
    finally:
        launch.stop_node(proc)
    return rows


def format_row(r: Dict) -> str:
    """One stream's figures as a line."""
    return (f'answered {r["answered"] * 100:.1f} % of {r["goals"]}, latency p50/p99 '
            f'{r["latency_p50"]:.2f}/{r["latency_p99"]:.2f} ms, staleness p50/p99 '
            f'{r["staleness_p50"]:.2f}/{r["staleness_p99"]:.2f} ms, last {r["last_answer"]:.2f} '
            f'ms, out of order {r["out_of_order"]}, stamped {r["stamped"]}/{r["answers"]}, '
            f'timeout {r["timeout"]}, jumps {r["joint_jump"]}, flips {r["flips"]}, invalid '
            f'{r["invalid"]}/{r["checked"]}, replaced {r["replaced_reported"]}, node CPU '
            f'{r["node_cpu"]:.0f} %')


def main(argv: Optional[List[str]] = None) -> int:
    """Run the benchmark; print and optionally write the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--rates', type=float, nargs='+', default=[100, 500, 1000])
    parser.add_argument('--duration', type=float, default=10.0, help='seconds per stream')
    parser.add_argument('--goals', nargs='+', default=['pose', 'position'],
                        choices=['pose', 'position'])
    parser.add_argument('--busy', action='store_true',
                        help='keep one core busy with another process meanwhile')
    parser.add_argument('--model-dir', default=None, help='a bundle (default: the Panda)')
    parser.add_argument('--param', action='append', default=[], metavar='NAME:=VALUE',
                        help='extra node parameter')
    parser.add_argument('--domain', type=int, default=None)
    add_json_argument(parser)
    args = parser.parse_args(argv)
    robot = SelectiveIK.load(args.model_dir or 'panda').robot
    busy = None
    if args.busy:
        busy = multiprocessing.Process(target=_spin_forever, daemon=True)
        busy.start()
    env = launch.ros_env(args.domain)
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    rows: List[Dict] = []
    try:
        for kind in args.goals:
            rows += run_kind(kind, args, robot, env)
    finally:
        rclpy.try_shutdown()
        if busy is not None:
            busy.terminate()
    if args.json:
        write_json(args.json, 'stream',
                   {'busy': args.busy, 'duration': args.duration, 'rows': rows,
                    'tolerances': {'position': 1e-4, 'orientation': 1e-3}})
    return 0


if __name__ == '__main__':
    sys.exit(main())
