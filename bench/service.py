"""Benchmark of sik_node's ``~/solve_ik`` over loopback DDS: latency, throughput, memory.

Measures, for goals at FK of random configurations (position goals, pose goals, or both
alternating: ``--goals mixed``) and 16 ranked refined solutions:

- round-trip latency of sequential requests (p50, p90, p99) [ms] from a :class:`SolveIKClient`
  (a background-spun client: ``spin_until_future_complete`` alone costs several ms per call),
  beside the solver's own time (``IKResult.elapsed``) for the same requests as the node reports
  it in each answer's message, and as measured in this process on the same targets, so the ROS
  overhead shows;
- the floor of a round trip in the same run: an empty ``std_srvs/Trigger`` service served as
  the node serves (``bench/empty_service.py``, a process beside the node), called by the same
  client code, one call of each in turn (A B A B), and the ratio of the two;
- the floor of an answer of the node's size, in the same turns: a ``SolveIK`` service of the
  same process answering every request with the same 16 solutions (solved once, converted as
  the node converts them): what rclpy's messages cost without a solve;
- throughput with 1 and with several concurrent clients [requests/s], of the node, the empty
  service and the message service, in alternating phases, and the processor time each
  answer took in the serving process and in the clients' process [ms] (``/proc``);
- resident memory (VmRSS) growth of the node and its solver processes over all the requests
  sent [MB].

Usage: ``python bench/service.py [--quick] [--requests N] [--goals position|pose|mixed]
[--clients N] [--duration S] [--model-dir DIR] [--domain ID] [--json PATH]``. Prints a table; the
figures are never asserted (see docs/benchmarks.md).
"""

import argparse
import os
from pathlib import Path
import re
import subprocess
import sys
import threading
import time
from typing import Callable, Dict, List, Optional

import numpy as np
import rclpy
from rclpy.signals import SignalHandlerOptions
from std_srvs.srv import Trigger

from sik_interfaces.srv import SolveIK
from sik_ros.kinematics.robots import load_robot
from sik_ros.ros import client as ros_client, launch
from sik_ros.ros.client import SolveIKClient
from sik_ros.serving.pool import single_threaded
from sik_ros.solver import SelectiveIK

import empty_service  # noqa: I100 (bench/empty_service.py)
from report import add_json_argument, write_json  # noqa: I100 (bench/report.py)

NUM_SOLUTIONS = 16
NODE_TIMEOUT = 0.05  # [s] config/panda.yaml
SERVICE = '/sik_node/solve_ik'
#: The solver time sik_node puts in its answers' message ('..., position goal, 4.2 ms').
SOLVER_MS = re.compile(r'goal, ([0-9.]+) ms')
#: Alternating phases of each service in a throughput measurement (the machine's pace drifts).
ROUNDS = 2


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
    """Format 'p50 / p90 / p99' in milliseconds (NaNs ignored)."""
    p50, p90, p99 = np.nanpercentile(np.asarray(seconds, dtype=float) * 1e3, [50, 90, 99])
    return f'{p50:.2f} / {p90:.2f} / {p99:.2f}'


class Service:
    """One service the benchmark calls: its name, type, the i-th call's request, its process.

    ``pid``: the process serving it, set once started.
    """

    def __init__(self, label: str, name: str, srv_type, request: Callable[[int], object]):
        self.label, self.name, self.srv_type, self.request = label, name, srv_type, request
        self.pid: Optional[int] = None

    def client(self, node_name: str) -> SolveIKClient:
        """A background-spun client of this service."""
        return SolveIKClient(self.name, node_name, srv_type=self.srv_type)


def services(goals: List[tuple]) -> Dict[str, Service]:
    """The node's ``~/solve_ik`` (``sik``), the empty (``floor``) and message services."""
    requests = [ros_client.pose_request(p, quat, max_solutions=NUM_SOLUTIONS)
                for p, quat in goals]
    empty = Trigger.Request()
    return {'sik': Service('sik_node ~/solve_ik', SERVICE, SolveIK,
                           lambda i: requests[i % len(requests)]),
            'floor': Service('empty Trigger service', empty_service.SERVICE, Trigger,
                             lambda i: empty),
            'message': Service('16-solution SolveIK service', empty_service.MESSAGE_SERVICE,
                               SolveIK, lambda i: requests[i % len(requests)])}


def cpu_seconds(pid: int) -> float:
    """Processor time (user + system) of a process and of its children's live processes [s]."""
    with open(f'/proc/{pid}/stat') as f:
        fields = f.read().rsplit(')', 1)[1].split()
    total = (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')
    for task in os.listdir(f'/proc/{pid}/task'):
        with open(f'/proc/{pid}/task/{task}/children') as f:
            total += sum(cpu_seconds(int(c)) for c in f.read().split())
    return total


def sequential(sik: SolveIKClient, floor: SolveIKClient, message: SolveIKClient,
               goals: List[tuple]):
    """Time one request per goal, one at a time, then the empty and message services in turn.

    The message service gets the same request.

    Returns:
        round trips [s], the node's solver time of each (from the answer's message) [s], the
        answer codes (None: no answer), the empty service's and the message service's round
        trips [s].
    """
    times, inside, codes, empty, canned = [], [], [], [], []
    nothing = Trigger.Request()
    for p, quat in goals:
        req = ros_client.pose_request(p, quat, max_solutions=NUM_SOLUTIONS)
        t0 = time.perf_counter()
        answer = sik.call(req)
        t1 = time.perf_counter()
        floor.call(nothing)
        t2 = time.perf_counter()
        message.call(req)
        canned.append(time.perf_counter() - t2)
        empty.append(t2 - t1)
        times.append(t1 - t0)
        codes.append(None if answer is None else answer.error_code)
        took = None if answer is None else SOLVER_MS.search(answer.message)
        inside.append(float(took.group(1)) * 1e-3 if took else np.nan)
    return times, inside, codes, empty, canned


def concurrent(service: Service, clients: int, duration: float):
    """Count answers to ``clients`` threads calling ``service`` back to back for ``duration`` [s].

    Returns:
        the answers and the wall time [s].
    """
    counts = [0] * clients
    start = threading.Barrier(clients + 1)
    stop = threading.Event()

    def run(k):
        with service.client(f'sik_bench_client_{k}') as cli:
            cli.wait_for_service(10.0)
            start.wait()
            i = k
            while not stop.is_set():
                counts[k] += cli.call(service.request(i)) is not None
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


def throughput(svcs: Dict[str, Service], clients: List[int], duration: float
               ) -> Dict[str, Dict[str, dict]]:
    """Requests/s of every service with each client count, phases alternating.

    Each (service, clients) pair gets ``ROUNDS`` phases of ``duration / ROUNDS`` seconds, in
    turn with the other services', so all see the same machine. The processor time of the
    serving process (``Service.pid``, its solver processes included) and of this one (the
    clients) is read around each phase.

    Returns:
        ``{str(clients): {key: {'answers', 'seconds', 'rps', 'server_cpu_ms',
        'client_cpu_ms'}}}`` for the keys of ``svcs`` (processor time per answer).
    """
    out: Dict[str, Dict[str, dict]] = {}
    for _ in range(ROUNDS):
        for k in clients:
            for key, svc in svcs.items():
                server0, client0 = cpu_seconds(svc.pid), time.process_time()
                answered, wall = concurrent(svc, k, duration / ROUNDS)
                server, client = cpu_seconds(svc.pid) - server0, time.process_time() - client0
                cell = out.setdefault(str(k), {}).setdefault(
                    key, {'answers': 0, 'seconds': 0.0, 'server_cpu': 0.0, 'client_cpu': 0.0})
                cell['answers'] += answered
                cell['seconds'] += wall
                cell['server_cpu'] += server
                cell['client_cpu'] += client
    for cells in out.values():
        for cell in cells.values():
            cell['rps'] = cell['answers'] / cell['seconds']
            per = 1e3 / max(cell['answers'], 1)
            cell['server_cpu_ms'] = cell.pop('server_cpu') * per
            cell['client_cpu_ms'] = cell.pop('client_cpu') * per
    return out


def in_process(bundle: str, goals: List[tuple]) -> List[float]:
    """Time the solver alone [s] on the same goals, as the node runs it (one thread).

    One thread for torch and NumPy's BLAS, as in the node (:func:`single_threaded`).
    """
    single_threaded()
    ik = SelectiveIK.load(bundle).with_config(position_tolerance=1e-4,
                                              orientation_tolerance=1e-3)
    ik.warm_up()
    for p, quat in goals[:10]:
        ik.solve(p, quat, num_solutions=NUM_SOLUTIONS, timeout=NODE_TIMEOUT)
    return [ik.solve(p, quat, num_solutions=NUM_SOLUTIONS, timeout=NODE_TIMEOUT).elapsed
            for p, quat in goals]


def figures(args: argparse.Namespace, n: int, duration: float, rtt, inside, empty, canned,
            solver, rates: Dict[str, Dict[str, dict]], rss0: float, rss1: float, ok: int,
            goals: List[tuple]) -> dict:
    """The printed figures as a dict for ``--json`` (times [ms], memory [MB])."""
    def pct(seconds) -> dict:
        p50, p90, p99 = np.nanpercentile(np.asarray(seconds, dtype=float) * 1e3, [50, 90, 99])
        return {'p50_ms': float(p50), 'p90_ms': float(p90), 'p99_ms': float(p99)}

    rtt_a, inside_a = np.asarray(rtt), np.asarray(inside)
    sik, floor, message = pct(rtt_a), pct(empty), pct(canned)
    answered = sum(cells['sik']['answers'] for cells in rates.values())
    out = {'goals': args.goals, 'requests': n, 'clients': args.clients,
           'duration_s': duration, 'params': args.param, 'solutions': NUM_SOLUTIONS,
           'round_trip': sik, 'floor_round_trip': floor,
           'ratio': {'p50': sik['p50_ms'] / floor['p50_ms'],
                     'p90': sik['p90_ms'] / floor['p90_ms']},
           'message_round_trip': message,
           'message_ratio': {'p50': message['p50_ms'] / floor['p50_ms'],
                             'p90': message['p90_ms'] / floor['p90_ms']},
           'solver_in_node': pct(inside_a),
           'overhead': pct(rtt_a - inside_a), 'solver_alone': pct(solver),
           'throughput_rps': rates[str(args.clients)]['sik']['rps'],
           'throughput': {k: {key: cell['rps'] for key, cell in cells.items()}
                          for k, cells in rates.items()},
           'cpu_ms_per_answer': {k: {key: {'server': cell['server_cpu_ms'],
                                           'client': cell['client_cpu_ms']}
                                     for key, cell in cells.items()}
                                 for k, cells in rates.items()},
           'rss_start_mb': rss0, 'rss_end_mb': rss1,
           'rss_growth_mb': rss1 - rss0, 'requests_total': n + answered,
           'success': ok / len(rtt)}
    if args.goals == 'mixed':
        pose = np.array([quat is not None for _, quat in goals])
        out['round_trip_position'] = pct(rtt_a[~pose])
        out['round_trip_pose'] = pct(rtt_a[pose])
    return out


def start_floor(env: Dict[str, str]) -> subprocess.Popen:
    """Start the empty service (bench/empty_service.py) as a process on the node's graph."""
    return subprocess.Popen([sys.executable, str(Path(__file__).with_name('empty_service.py'))],
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--quick', action='store_true',
                        help='a short run: 200 requests, 3 s per throughput phase')
    parser.add_argument('--requests', type=int,
                        help='sequential requests for latency and memory (default 10000)')
    parser.add_argument('--clients', type=int, default=4, help='concurrent clients')
    parser.add_argument('--duration', type=float,
                        help='throughput of each service with each client count [s] '
                        '(default 20)')
    parser.add_argument('--goals', choices=('position', 'pose', 'mixed'), default='position',
                        help='goal kinds of the requests (mixed: alternating)')
    parser.add_argument('--model-dir', help='bundle directory (default: the bundled panda)')
    parser.add_argument('--domain', type=int,
                        help='ROS_DOMAIN_ID of the node, the empty service and the clients '
                        '(default: a random one of 1 to 100)')
    parser.add_argument('-p', '--param', action='append', default=[],
                        help='a node parameter override name:=value (repeatable)')
    add_json_argument(parser)
    args = parser.parse_args(argv)
    n = args.requests or (200 if args.quick else 10_000)
    duration = args.duration or (3.0 if args.quick else 20.0)
    bundle = args.model_dir or 'panda'
    goals = targets(n, kinds=args.goals)

    env = launch.ros_env(args.domain)
    proc = launch.launch_node(args.model_dir, args.param, env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.STDOUT)
    floor_proc = start_floor(env)
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    try:
        if not launch.service_up(SolveIK, SERVICE, proc):
            print(f'sik_node did not come up (exit code {proc.poll()})')
            return 1
        svcs = services(goals)
        svcs['sik'].pid = proc.pid
        svcs['floor'].pid = svcs['message'].pid = floor_proc.pid
        with svcs['sik'].client('sik_bench') as client, \
                svcs['floor'].client('sik_bench_floor') as floor, \
                svcs['message'].client('sik_bench_message') as message:
            if not (floor.wait_for_service(60.0) and message.wait_for_service(10.0)):
                print(f'the empty service did not come up (exit code {floor_proc.poll()})')
                return 1
            client.wait_for_service(10.0)
            sequential(client, floor, message, targets(20, seed=1, kinds=args.goals))  # warm-up
            rss0 = vm_rss_mb(proc.pid)
            rtt, inside, codes, empty, canned = sequential(client, floor, message, goals)
        rates = throughput(svcs, sorted({1, args.clients}), duration)
        rss1 = vm_rss_mb(proc.pid)
    finally:
        launch.stop_node(floor_proc)
        launch.stop_node(proc)
        rclpy.try_shutdown()
    solver = in_process(bundle, goals)
    ok = sum(c == SolveIK.Response.SUCCESS for c in codes)
    data = figures(args, n, duration, rtt, inside, empty, canned, solver, rates, rss0, rss1, ok,
                   goals)
    ratio = data['ratio']
    rows = [
        ('round trip p50 / p90 / p99 [ms]', percentiles(rtt), ''),
        ('empty service round trip p50 / p90 / p99 [ms]', percentiles(empty), ''),
        ('round trip / empty service, p50 / p90',
         f'{ratio["p50"]:.2f} / {ratio["p90"]:.2f}', '<= 2.0 (p50)'),
        ('16-solution message service round trip p50 / p90 / p99 [ms]', percentiles(canned),
         ''),
        ('message service / empty service, p50 / p90',
         f'{data["message_ratio"]["p50"]:.2f} / {data["message_ratio"]["p90"]:.2f}', ''),
        ('solver in the node p50 / p90 / p99 [ms]', percentiles(inside), ''),
        ('ROS overhead (round trip - solver) p50 / p90 / p99 [ms]',
         percentiles(np.asarray(rtt) - np.asarray(inside)), ''),
        ('solver alone p50 / p90 / p99 [ms] (this process)', percentiles(solver), ''),
    ]
    for k, cells in data['throughput'].items():
        rows.append((f'throughput, {k} client{"s" if k != "1" else ""}: node / message / '
                     f'empty service [req/s]',
                     f'{cells["sik"]:.0f} / {cells["message"]:.0f} / {cells["floor"]:.0f}',
                     '>= 600 (node)' if k == str(args.clients) else ''))
        cpu = data['cpu_ms_per_answer'][k]
        rows.append(('  processor time per answer, server + clients: node / message / '
                     'empty [ms]', ' / '.join(f'{cpu[key]["server"]:.2f} + '
                                              f'{cpu[key]["client"]:.2f}'
                                              for key in ('sik', 'message', 'floor')), ''))
    rows += [
        (f'node RSS growth over {data["requests_total"]} requests [MB]',
         f'{rss1 - rss0:+.1f} ({rss0:.0f} -> {rss1:.0f})', '< 10 over 10,000'),
        ('SUCCESS answers (sequential)', f'{ok}/{len(codes)}', ''),
    ]
    if args.goals == 'mixed':
        pose = np.array([quat is not None for _, quat in goals])
        rtt_a = np.asarray(rtt)
        rows[1:1] = [('  position goals: round trip p50 / p90 / p99 [ms]',
                      percentiles(rtt_a[~pose]), ''),
                     ('  pose goals: round trip p50 / p90 / p99 [ms]',
                      percentiles(rtt_a[pose]), '')]
    print(f'sik_node ~/solve_ik over loopback DDS: bundle {bundle}, {args.goals} goals, '
          f'{NUM_SOLUTIONS} ranked refined solutions, node timeout {NODE_TIMEOUT * 1e3:.0f} ms'
          + (f', parameters {" ".join(args.param)}' if args.param else '')
          + (' (quick run)' if args.quick else ''))
    write_json(args.json, 'service', data)
    width = max(len(r[0]) for r in rows)
    print(f"| {'metric':<{width}} | {'measured':>22} | {'target':>16} |")
    print(f"|{'-' * (width + 2)}|{'-' * 24}|{'-' * 18}|")
    for name, value, goal in rows:
        print(f'| {name:<{width}} | {value:>22} | {goal:>16} |')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
