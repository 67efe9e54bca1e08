"""TRAC-IK's own published protocol, ours beside it: one pose solution from the mid-limits seed.

TRAC-IK's README reports, per arm, the success and mean time of 10,000 random reachable poses
(FK of uniform random configurations) solved from the middle of the joint limits with a 5 ms
budget. Here both solvers answer each pose in turn (A B A B, the order alternating): ours with
``num_solutions=1``, the same seed and a 5 ms timeout; TRAC-IK (pytracik: Speed, eps 1e-5).
Success is each solver's own: ours within its tolerances (0.1 mm, 0.001 rad), TRAC-IK's status.

    python bench/tracik_protocol.py --targets 10000 --json docs/results/tracik_protocol.json
"""

import argparse
import os
import time

os.environ.setdefault('OMP_NUM_THREADS', '1')

import numpy as np  # noqa: E402
import torch  # noqa: E402

from sik_ros.solver import SelectiveIK  # noqa: E402

from peers import TracIK  # noqa: E402,I100 (bench/peers.py)
from report import add_json_argument, write_json  # noqa: E402 (bench/report.py)


def main() -> None:
    """Run the protocol and print (and optionally save) success and mean times."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--bundle', default='panda')
    parser.add_argument('--targets', type=int, default=10000)
    parser.add_argument('--timeout', type=float, default=0.005, help='both solvers [s]')
    parser.add_argument('--seed', type=int, default=2024)
    add_json_argument(parser)
    args = parser.parse_args()
    torch.set_num_threads(1)
    ik = SelectiveIK.load(args.bundle)
    ik.warm_up()
    robot = ik.robot
    peer = TracIK(robot, args.timeout)
    rng = np.random.default_rng(args.seed)
    q = rng.uniform(robot.lower, robot.upper, (args.targets, robot.dof))
    pos, quat = robot.fk_batch(q)
    mid = (robot.lower + robot.upper) / 2
    times = {'sik_ros': [], 'TRAC-IK': []}
    ok = {'sik_ros': [], 'TRAC-IK': []}

    def ours(i):
        res = ik.solve(pos[i], quat[i], 1, seed=mid, timeout=args.timeout)
        return res.success

    def theirs(i):
        return peer.solve(pos[i], quat[i], mid)[0]
    for i in range(args.targets):
        order = (('sik_ros', ours), ('TRAC-IK', theirs))
        for name, call in (order if i % 2 == 0 else order[::-1]):
            t0 = time.perf_counter()
            good = call(i)
            times[name].append(time.perf_counter() - t0)
            ok[name].append(bool(good))
    results = {}
    print(f'# bench/tracik_protocol.py: bundle {args.bundle}, {args.targets} random reachable '
          f'poses (seed {args.seed}), seed at mid-limits, {args.timeout * 1e3:g} ms budget')
    print('| solver | success | mean time [ms] | median [ms] | p99 [ms] |')
    print('|---|---|---|---|---|')
    for name in times:
        t = np.array(times[name]) * 1e3
        results[name] = {'success': float(np.mean(ok[name])), 'mean_ms': float(t.mean()),
                         'median_ms': float(np.median(t)),
                         'p99_ms': float(np.percentile(t, 99))}
        r = results[name]
        print(f"| {name} | {100 * r['success']:.2f} % | {r['mean_ms']:.3f} | "
              f"{r['median_ms']:.3f} | {r['p99_ms']:.3f} |")
    ratio = results['sik_ros']['mean_ms'] / results['TRAC-IK']['mean_ms']
    results['mean_ratio'] = ratio
    print(f'mean time ratio sik_ros / TRAC-IK: {ratio:.2f}')
    write_json(args.json, 'tracik_protocol', results)


if __name__ == '__main__':
    main()
