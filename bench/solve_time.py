"""Time SelectiveIK alone over seeded targets (no peers): for paired runs between two commits.

Targets are FK of configurations drawn uniformly in joint space (seeded), as in
``bench/solve.py``. Prints the median and mean time per call and the success and distinct
counts, per goal kind. Pair two checkouts with a whole-process timer, A B A B, e.g.

    PYTHONPATH=/path/to/other/checkout python bench/solve_time.py --targets 300
"""

import argparse
import os
import time

os.environ.setdefault('OMP_NUM_THREADS', '1')

import numpy as np  # noqa: E402
import torch  # noqa: E402

from sik_ros import SelectiveIK  # noqa: E402


def main() -> None:
    """Solve every target once per goal kind and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--targets', type=int, default=300)
    parser.add_argument('--bundle', default='panda')
    parser.add_argument('--goals', default='position,pose')
    parser.add_argument('--seed', type=int, default=0)
    args = parser.parse_args()
    torch.set_num_threads(1)
    ik = SelectiveIK.load(args.bundle)
    rng = np.random.default_rng(args.seed)
    q = rng.uniform(ik.robot.lower, ik.robot.upper, (args.targets, ik.robot.dof))
    poses = [ik.fk(qi) for qi in q]
    for goal in args.goals.split(','):
        times, ok, distinct = [], 0, []
        for p, quat in poses:
            t0 = time.perf_counter()
            res = ik.solve(p, quat if goal == 'pose' else None, num_solutions=16)
            times.append(time.perf_counter() - t0)
            ok += res.success
            distinct.append(sum(s.converged for s in res.solutions))
        print(f'{goal}: success {ok}/{len(poses)}, distinct median {np.median(distinct):.0f} '
              f'p10 {np.percentile(distinct, 10):.0f}, time median '
              f'{1e3 * np.median(times):.2f} ms mean {1e3 * np.mean(times):.2f} ms')


if __name__ == '__main__':
    main()
