"""Benchmark of sik_node's ``~/solve_ik_batch`` against as many ``~/solve_ik`` calls, paired.

The same targets (goals at FK of random Panda configurations, pose goals by default) are
answered by one ``~/solve_ik_batch`` request and by one ``~/solve_ik`` call per target, one
after the other from one client each (a background-spun :class:`SolveIKClient` for each, in
this process), in turn: A B A B over ``--repeats`` rounds, so that both see the same machine. For
each it prints the throughput [targets/s] (the median round and the total over every round),
the time per target [ms] and the ratio batch / calls of each round's throughputs (median, and
the range). Every answer is checked by Pinocchio's FK of the returned joint values
(``Robot.pin_placement``): the targets answered SUCCESS, the solutions the node reports within
tolerance and how many of them are within it by FK, and whether each SUCCESS answer's best
solution is exact.

Usage: ``python bench/batch_service.py [--targets N] [--repeats N] [--goals pose|position|mixed]
[--solutions K] [--model-dir DIR] [-p NAME:=VALUE] [--domain ID] [--json PATH]``. Prints a
table; the figures are never asserted (see docs/benchmarks.md).
"""

import argparse
import subprocess
import time
from typing import Dict, List, Optional, Tuple

import numpy as np
import pinocchio as pin
import rclpy
from rclpy.signals import SignalHandlerOptions

from sik_interfaces.srv import SolveIK, SolveIKBatch
from sik_ros.kinematics.robots import load_robot
from sik_ros.ros import launch
from sik_ros.ros.client import batch_request, pose_request, SolveIKClient

from report import add_json_argument, write_json  # noqa: I100 (bench/report.py)

SINGLE = '/sik_node/solve_ik'
BATCH = '/sik_node/solve_ik_batch'
NODE_TIMEOUT = 0.05  # [s] config/panda.yaml: each target's budget (the requests give 0)
POS_TOL, ROT_TOL = 1e-4, 1e-3  # [m], [rad] config/panda.yaml
#: A batch call waits this long for its answer before it sends the request again [s].
BATCH_ATTEMPT = 120.0


Goal = Tuple[np.ndarray, Optional[np.ndarray]]


def goals(robot, count: int, seed: int, kinds: str) -> List[Goal]:
    """Reachable goals: (position (3,) [m], quaternion (4,) x y z w or None) per target.

    ``kinds``: ``pose``, ``position``, or ``mixed`` (pose goals at odd places). A batch holds one
    goal kind (``use_orientation``), so ``mixed`` sends its two kinds as two batches.
    """
    q = np.random.default_rng(seed).uniform(robot.lower, robot.upper, (count, robot.dof))
    pos, quat = robot.fk_batch(q)
    pose = [kinds == 'pose' or (kinds == 'mixed' and i % 2 == 1) for i in range(count)]
    return [(pos[i], quat[i] if pose[i] else None) for i in range(count)]


def batch_requests(targets, solutions: int) -> List[Tuple[List[int], SolveIKBatch.Request]]:
    """The batch requests of the targets: (their indices, the request), one per goal kind."""
    out = []
    for pose in (True, False):
        rows = [i for i, (_, quat) in enumerate(targets) if (quat is not None) == pose]
        if rows:
            out.append((rows, batch_request([targets[i][0] for i in rows],
                                            [targets[i][1] for i in rows] if pose else None,
                                            max_solutions=solutions)))
    return out


def by_batch(client: SolveIKClient, requests, count: int) -> Tuple[float, list]:
    """Time the batch requests [s]; each target's answer (a ``SolveIKResult``; None: none)."""
    answers: List[Optional[object]] = [None] * count
    t0 = time.perf_counter()
    replies = [(rows, client.call(request, timeout=BATCH_ATTEMPT * 2, attempt=BATCH_ATTEMPT))
               for rows, request in requests]
    seconds = time.perf_counter() - t0
    for rows, reply in replies:
        if reply is not None and reply.error_code == SolveIKBatch.Response.SUCCESS:
            for i, result in zip(rows, reply.results):
                answers[i] = result
    return seconds, answers


def by_calls(client: SolveIKClient, requests) -> Tuple[float, list]:
    """Time one ``~/solve_ik`` call per target, one after the other [s]; the answers."""
    t0 = time.perf_counter()
    answers = [client.call(request) for request in requests]
    return time.perf_counter() - t0, answers


def exactness(robot, targets, answers) -> Dict[str, int]:
    """Counts of SUCCESS answers, reported-exact solutions and of those exact by Pinocchio's FK.

    ``best_exact``: SUCCESS answers whose best solution is within both tolerances by FK.
    """
    out = {'answers': 0, 'success': 0, 'best_exact': 0, 'solutions': 0, 'marked_exact': 0,
           'exact_by_fk': 0}
    for (position, quat), answer in zip(targets, answers):
        if answer is None:
            continue
        out['answers'] += 1
        goal = None if quat is None else pin.Quaternion(quat[3], *quat[:3]).normalized().matrix()
        exact = []
        for s in answer.solutions:
            tip = robot.pin_placement(np.array(s.joint_state.position))
            ok = np.linalg.norm(tip.translation - position) <= POS_TOL
            if goal is not None:
                ok = ok and np.linalg.norm(pin.log3(goal.T @ tip.rotation)) <= ROT_TOL + 1e-9
            marked = s.position_error <= POS_TOL and s.orientation_error <= ROT_TOL
            out['solutions'] += 1
            out['marked_exact'] += marked
            out['exact_by_fk'] += bool(marked and ok)
            exact.append(ok)
        if answer.error_code == SolveIK.Response.SUCCESS:
            out['success'] += 1
            out['best_exact'] += bool(exact and exact[0])
    return out


def figures(args, count: int, rounds: List[Dict[str, float]], checks: Dict[str, Dict[str, int]]
            ) -> dict:
    """The printed figures as a dict for ``--json`` (throughput [targets/s], times [ms])."""
    out = {'targets': count, 'repeats': args.repeats, 'goals': args.goals,
           'solutions': args.solutions, 'node_timeout_s': NODE_TIMEOUT, 'params': args.param,
           'rounds': rounds, 'checks': checks}
    for key in ('batch', 'calls'):
        seconds = np.array([r[f'{key}_s'] for r in rounds])
        out[key] = {'throughput_median': float(np.median(count / seconds)),
                    'throughput_total': float(count * len(seconds) / seconds.sum()),
                    'ms_per_target_median': float(np.median(seconds) / count * 1e3)}
    ratios = np.array([r['calls_s'] / r['batch_s'] for r in rounds])
    out['ratio'] = {'median': float(np.median(ratios)), 'min': float(ratios.min()),
                    'max': float(ratios.max())}
    return out


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--targets', type=int, default=200, help='targets per round')
    parser.add_argument('--repeats', type=int, default=5,
                        help='rounds, each a batch and the calls (A B A B)')
    parser.add_argument('--goals', choices=('pose', 'position', 'mixed'), default='pose',
                        help='goal kinds (mixed: pose goals at odd places, one batch per kind)')
    parser.add_argument('--solutions', type=int, default=16, help='solutions asked per target')
    parser.add_argument('--model-dir', help='bundle directory (default: the bundled panda)')
    parser.add_argument('--domain', type=int,
                        help='ROS_DOMAIN_ID of the node and the clients (default: random)')
    parser.add_argument('-p', '--param', action='append', default=[],
                        help='a node parameter override name:=value (repeatable)')
    add_json_argument(parser)
    args = parser.parse_args(argv)
    robot = load_robot('panda')
    targets = goals(robot, args.targets, 0, args.goals)
    batches = batch_requests(targets, args.solutions)
    singles = [pose_request(p, quat, max_solutions=args.solutions) for p, quat in targets]

    env = launch.ros_env(args.domain)
    proc = launch.launch_node(args.model_dir, args.param, env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.STDOUT)
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    rounds: List[Dict[str, float]] = []
    answers: Dict[str, list] = {'batch': [], 'calls': []}
    try:
        if not launch.service_up(SolveIKBatch, BATCH, proc):
            print(f'sik_node did not come up (exit code {proc.poll()})')
            return 1
        with SolveIKClient(BATCH, 'sik_bench_batch', srv_type=SolveIKBatch) as batch, \
                SolveIKClient(SINGLE, 'sik_bench_calls') as single:
            batch.wait_for_service(10.0)
            single.wait_for_service(10.0)
            warm = goals(robot, 20, 1, args.goals)  # warm-up: both paths, other targets
            by_batch(batch, batch_requests(warm, args.solutions), len(warm))
            by_calls(single, [pose_request(p, quat, max_solutions=args.solutions)
                              for p, quat in warm])
            for _ in range(args.repeats):
                batch_s, batch_answers = by_batch(batch, batches, len(targets))
                calls_s, call_answers = by_calls(single, singles)
                rounds.append({'batch_s': batch_s, 'calls_s': calls_s})
                answers['batch'] += batch_answers
                answers['calls'] += call_answers
    finally:
        launch.stop_node(proc)
        rclpy.try_shutdown()
    checks = {key: exactness(robot, targets * args.repeats, found)
              for key, found in answers.items()}
    data = figures(args, len(targets), rounds, checks)
    write_json(args.json, 'batch_service', data)

    total = len(targets) * args.repeats
    rows = []
    for key, label in (('batch', 'one ~/solve_ik_batch'), ('calls', '~/solve_ik calls')):
        d, c = data[key], checks[key]
        rows.append((f'{label}: throughput, median round / total [targets/s]',
                     f'{d["throughput_median"]:.0f} / {d["throughput_total"]:.0f}'))
        rows.append((f'{label}: time per target, median round [ms]',
                     f'{d["ms_per_target_median"]:.2f}'))
        rows.append((f'{label}: answered / SUCCESS / best solution exact by FK',
                     f'{c["answers"]}/{total} / {c["success"]} / {c["best_exact"]}'))
        rows.append((f'{label}: solutions within tolerance, as reported / by FK',
                     f'{c["marked_exact"]} / {c["exact_by_fk"]} (of {c["solutions"]})'))
    ratio = data['ratio']
    rows.append(('throughput ratio batch / calls, median round (range)',
                 f'{ratio["median"]:.2f} ({ratio["min"]:.2f}-{ratio["max"]:.2f})'))
    print(f'sik_node ~/solve_ik_batch against ~/solve_ik over loopback DDS: bundle '
          f'{args.model_dir or "panda"}, {len(targets)} {args.goals} goals per round, '
          f'{args.repeats} rounds (A B A B), {args.solutions} solutions asked, node timeout '
          f'{NODE_TIMEOUT * 1e3:.0f} ms per target'
          + (f', parameters {" ".join(args.param)}' if args.param else ''))
    width = max(len(r[0]) for r in rows)
    value = max(len(r[1]) for r in rows)
    print(f"| {'metric':<{width}} | {'measured':>{value}} |")
    print(f"|{'-' * (width + 2)}|{'-' * (value + 2)}|")
    for name, measured in rows:
        print(f'| {name:<{width}} | {measured:>{value}} |')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
