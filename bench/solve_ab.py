"""Paired A/B of SelectiveIK.solve between checkouts: each answers the same targets in turn.

Every checkout runs in its own worker process (its ``sik_ros`` first on the path) on the same
bundle; target by target the workers take turns, the order flipping every target, so the
machine's drift falls on both alike. Targets are FK of configurations drawn uniformly in joint
space (seeded). Prints per checkout: success, distinct exact solutions (mean), branches (mean:
distinct with angles wrapped to one turn), the median time per call and the median of the
per-target time ratios to the first checkout. With ``--busy MS`` each worker first does that many
milliseconds of other work (a NumPy loop) before each call: a call then finds the caches
emptied, as a service's requests and the calls in ``bench/arms.py`` (after the peer's) do.

    python bench/solve_ab.py old=/path/to/checkout new=. --bundle DIR --goal pose
    python bench/solve_ab.py old=/path/to/checkout new=. --bundle DIR --busy 90
    python bench/solve_ab.py a=. b=. --goal pose --json docs/results/solve_ab-panda-pose.json

A checkout spec ``NAME=tracik`` (pose goals), ``NAME=frankik`` (the Panda's analytic IK, pose
goals) or ``NAME=dls`` (position goals) is a peer in the same turns instead: with ``--num 1``
one call from the same seed (the target's random current state with ``--seeded``, else a random
one); with more, calls from random seeds until as many
distinct solutions as asked for (or 300 attempts); ``--peer-num 1`` times one peer call beside
calls asking for more (an arm whose poses have one solution: ours returns every branch).
"""

import argparse
import json
import os
import sys
import time

os.environ.setdefault('OMP_NUM_THREADS', '1')

import numpy as np  # noqa: E402

from ab import answers_in_turn  # noqa: E402,I100 (bench/ab.py, beside this script)
from report import add_json_argument, git_commit, write_json  # noqa: E402 (bench/report.py)


def busy(ms: float) -> None:
    """``ms`` milliseconds of other work: NumPy on an array the size of a cache's share."""
    x = np.ones(100_000)
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < ms / 1e3:
        x = np.sin(x) + 1.0


def worker(root: str, bundle: str, goal: str, num: int, seeded: bool, seed: int,
           count: int, busy_ms: float, peer_num: int) -> None:
    """Answer target numbers read from stdin with one JSON line each (run in a subprocess)."""
    here = os.path.dirname(os.path.abspath(__file__))
    peer = root.rstrip('/').rsplit('/', 1)[-1] \
        if os.path.basename(root) in ('tracik', 'frankik', 'dls') else None
    sys.path.insert(0, os.path.dirname(here) if peer else root)
    sys.path.insert(0, here)
    import torch
    from arms import branches
    from sik_ros import SelectiveIK
    from sik_ros.solver.context import tip_on_last_axis
    from sik_ros.solver.scores import distinct_mask
    torch.set_num_threads(1)
    ik = SelectiveIK.load(bundle)
    robot = ik.robot
    roll_free = goal == 'position' and tip_on_last_axis(robot)

    def distinct(qs):  # the solver's own rule (in any checkout)
        return distinct_mask(qs, ik.config.distinct_threshold, roll_free)
    rng = np.random.default_rng(seed)
    q = rng.uniform(robot.lower, robot.upper, (count, robot.dof))
    seeds = rng.uniform(robot.lower, robot.upper, (count, robot.dof))
    targets = [robot.fk(qi) for qi in q]
    if peer:
        num = peer_num or num
        from peers import DLS, Frankik, TracIK
        out = os.dup(1)
        os.dup2(2, 1)  # TRAC-IK's URDF parser prints to stdout, which carries the answers
        solver = {'tracik': TracIK, 'frankik': Frankik, 'dls': DLS}[peer](robot)
        os.dup2(out, 1)
        draws = np.random.default_rng(seed + 1)

        def call(p, quat, q0):
            return solver.solve(p, q0) if peer == 'dls' else solver.solve(p, quat, q0)
        call(targets[0][0], targets[0][1], seeds[0])  # warm-up
    else:
        ik.solve(targets[0][0], targets[0][1] if goal == 'pose' else None,
                 num_solutions=num)  # warm-up
    print('ready', flush=True)
    for line in sys.stdin:
        k = int(line)
        p, quat = targets[k]
        if busy_ms > 0:
            busy(busy_ms)
        if peer:
            found, attempts = [], 0
            t0 = time.perf_counter()
            while attempts < (1 if num == 1 else 300):
                q0 = seeds[k] if seeded and attempts == 0 else \
                    draws.uniform(robot.lower, robot.upper)
                ok, qk = call(p, quat, q0)
                attempts += 1
                if ok:
                    found.append(qk)
                    if len(found) >= num and distinct(np.array(found)).sum() >= num:
                        break
            t = time.perf_counter() - t0
            exact = np.array(found).reshape(-1, robot.dof)
            success = bool(len(found))
        else:
            t0 = time.perf_counter()
            res = ik.solve(p, quat if goal == 'pose' else None, num_solutions=num,
                           seed=seeds[k] if seeded else None)
            t = time.perf_counter() - t0
            exact = np.array([s.q for s in res.solutions if s.converged]).reshape(-1, robot.dof)
            success = bool(res.success)
        print(json.dumps({'ok': success, 't': t * 1e3,
                          'n': int(distinct(exact).sum()) if len(exact) else 0,
                          'b': branches(exact)}), flush=True)


def main() -> None:
    """Start one worker per checkout, hand out the targets in turn and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('checkouts', nargs='+', help='NAME=DIR, the first is the reference')
    parser.add_argument('--bundle', default='panda')
    parser.add_argument('--goal', choices=('position', 'pose'), default='pose')
    parser.add_argument('--num', type=int, default=16, help='solutions asked for')
    parser.add_argument('--seeded', action='store_true', help='a random current state each')
    parser.add_argument('--targets', type=int, default=100)
    parser.add_argument('--seed', type=int, default=2024)
    parser.add_argument('--busy', type=float, default=0.0,
                        help='milliseconds of other work before each call (cold calls)')
    parser.add_argument('--peer-num', type=int, default=0,
                        help='solutions a peer looks for (default: --num)')
    parser.add_argument('--worker', nargs=9, help=argparse.SUPPRESS)
    add_json_argument(parser)
    args = parser.parse_args()
    if args.worker:
        root, bundle, goal, num, seeded, seed, count, busy_ms, peer_num = args.worker
        worker(root, bundle, goal, int(num), seeded == '1', int(seed), int(count),
               float(busy_ms), int(peer_num))
        return
    answers = answers_in_turn(__file__, args.checkouts,
                              [args.bundle, args.goal, str(args.num), str(int(args.seeded)),
                               str(args.seed), str(args.targets), str(args.busy),
                               str(args.peer_num)],
                              args.targets)
    first = next(iter(answers))
    ref = answers[first]
    print(f'# bench/solve_ab.py: {args.targets} {args.goal} targets of {args.bundle} (seed '
          f'{args.seed}), {args.num} solutions{", seeded" if args.seeded else ""}'
          f'{f", {args.busy:g} ms of other work before each call" if args.busy else ""}, '
          f'A B A B')
    print(f'| checkout | success | distinct (mean) | branches (mean) | time per call (median) '
          f'| ratio to {first} (median) |')
    print('|---|---|---|---|---|---|')
    figures = []
    for spec, name in zip(args.checkouts, answers):
        rows = answers[name]
        root = spec.partition('=')[2]
        f = {'name': name, **(git_commit(root) if os.path.isdir(root) else {'peer': root}),
             'success': float(np.mean([a['ok'] for a in rows])),
             'distinct_mean': float(np.mean([a['n'] for a in rows])),
             'branches_mean': float(np.mean([a['b'] for a in rows])),
             'time_median_ms': float(np.median([a['t'] for a in rows])),
             'ratio_median': float(np.median([a['t'] / b['t'] for a, b in zip(rows, ref)]))}
        figures.append(f)
        print(f'| {name} | {100 * f["success"]:.1f} % | {f["distinct_mean"]:.2f} '
              f'| {f["branches_mean"]:.2f} | {f["time_median_ms"]:.2f} ms '
              f'| {f["ratio_median"]:.3f} |')
    write_json(args.json, 'solve_ab', {
        'bundle': args.bundle, 'goal': args.goal, 'num': args.num, 'seeded': args.seeded,
        'targets': args.targets, 'seed': args.seed, 'busy_ms': args.busy,
        'checkouts': figures})


if __name__ == '__main__':
    main()
