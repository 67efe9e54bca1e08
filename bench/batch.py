"""solve_batch against the serial loop of solve on the same pose goals, paired.

Prints the throughput ratio (serial time / batch time, the median of ``--repeats`` pairs run
in turn, and its range), the success and distinct-solution
counts of both (equal: the batch answers are solve's) and whether every solution returned as
exact is exact by Pinocchio's FK. ``--threads`` also times a pool of threads over clones, the
alternative the processes replace.

    python bench/batch.py --targets 2000 --workers 2
"""

import argparse
from concurrent.futures import ThreadPoolExecutor
import os
import time

import numpy as np
import pinocchio as pin
from report import add_json_argument, write_json

from sik_ros import SelectiveIK


def pose_goals(ik, count, seed=0):
    """FK of random configurations within the limits: positions (N, 3), quaternions (N, 4)."""
    q = np.random.default_rng(seed).uniform(ik.robot.lower, ik.robot.upper,
                                            (count, ik.robot.dof))
    pos, quat = zip(*(ik.fk(qi) for qi in q))
    return np.array(pos), np.array(quat)


def exact_by_pinocchio(ik, results, pos, quat):
    """(solutions marked exact, of them exact by Pinocchio's FK)."""
    marked = held = 0
    tol_p, tol_o = ik.config.position_tolerance, ik.config.orientation_tolerance
    for res, p, qt in zip(results, pos, quat):
        goal = pin.Quaternion(qt[3], *qt[:3]).normalized().matrix()
        for s in res.solutions:
            if s.position_error <= tol_p and s.orientation_error <= tol_o:
                marked += 1
                tip = ik.robot.pin_placement(s.q)
                held += (np.linalg.norm(tip.translation - p) <= tol_p * 1.01
                         and np.linalg.norm(pin.log3(goal.T @ tip.rotation)) <= tol_o * 1.01)
    return marked, held


def main():
    """Time both, print the figures."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('--bundle', default='panda')
    p.add_argument('--targets', type=int, default=2000)
    p.add_argument('--solutions', type=int, default=16)
    p.add_argument('--workers', type=int, default=2)
    p.add_argument('--threads', action='store_true', help='also time threads over clones')
    p.add_argument('--repeats', type=int, default=3,
                   help='serial and batch runs, in turn (the ratio: their median)')
    add_json_argument(p)
    args = p.parse_args()
    ik = SelectiveIK.load(args.bundle)
    pos, quat = pose_goals(ik, args.targets)
    ik.warm_up()
    load0 = os.getloadavg()[0]
    serial_times, batch_times = [], []
    for _ in range(args.repeats):  # A B A B: the machine's drift falls on both alike
        t = time.perf_counter()
        serial = [ik.solve(a, b, num_solutions=args.solutions) for a, b in zip(pos, quat)]
        serial_times.append(time.perf_counter() - t)
        t = time.perf_counter()
        batch = ik.solve_batch(pos, quat, num_solutions=args.solutions, workers=args.workers)
        batch_times.append(time.perf_counter() - t)
    ratios = np.array(serial_times) / np.array(batch_times)
    t_serial, t_batch = float(np.median(serial_times)), float(np.median(batch_times))
    figures = dict(targets=args.targets, workers=args.workers, repeats=args.repeats,
                   serial_s=t_serial, batch_s=t_batch, ratio=float(np.median(ratios)),
                   ratio_range=[float(ratios.min()), float(ratios.max())],
                   success=[sum(r.success for r in serial), sum(r.success for r in batch)],
                   solutions=[sum(len(r.solutions) for r in serial),
                              sum(len(r.solutions) for r in batch)])
    if args.threads:
        clones = [ik.clone() for _ in range(args.workers)]
        t = time.perf_counter()
        with ThreadPoolExecutor(args.workers) as pool:
            list(pool.map(lambda i: clones[i % args.workers].solve(
                pos[i], quat[i], num_solutions=args.solutions), range(len(pos))))
        figures['threads_s'] = time.perf_counter() - t
        figures['threads_ratio'] = t_serial / figures['threads_s']
    figures['exact_marked'], figures['exact_by_pinocchio'] = exact_by_pinocchio(ik, batch, pos,
                                                                                quat)
    figures['load_average'] = [load0, os.getloadavg()[0]]
    for key, value in figures.items():
        print(f'{key:>20}: {value}')
    write_json(args.json, 'batch', figures)


if __name__ == '__main__':
    main()
