"""Paired A/B of solve_path between checkouts: each answers the same paths in turn, A B A B.

Every checkout runs in its own worker process (its ``sik_ros`` first on the path) on the same
bundle (``--bundle``, default the bundled Panda); path by
path the workers take turns, the order flipping every path, so the machine's drift falls on
both alike. Paths come from ``bench/paths.py``'s generator (lines and arcs, every other one
with the tool orientation held), each solved from a random current state. Prints, per goal
kind and checkout, whole-path success, the median time per path, the median of the per-path
time ratios to the first checkout, and the median travel, largest step and distance of the
start from the current state (L2 over the joints) of the best path; the travel also path by
path against the first checkout's, on the paths both solve.

    python bench/paths_ab.py --paths 80 old=/path/to/other/checkout new=.
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


def worker(root: str, seed: int, count: int, bundle: str = 'panda') -> None:
    """Answer path numbers read from stdin with one JSON line each (run in a subprocess)."""
    sys.path.insert(0, root)
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import torch
    from paths import Continuation, make_path
    from sik_ros import SelectiveIK
    torch.set_num_threads(1)
    ik = SelectiveIK.load(bundle)
    robot = ik.robot
    cont = Continuation(robot)
    rng = np.random.default_rng(seed)
    cases = []
    for k in range(count):
        pos, _, quats, _, _ = make_path(rng, robot, cont, ik.checker)
        cases.append((pos, quats if k % 2 == 0 else None,
                      rng.uniform(robot.lower, robot.upper)))
    ik.solve_path(cases[0][0], cases[0][1], seed=cases[0][2])  # warm-up
    print('ready', flush=True)
    for line in sys.stdin:
        pos, quats, q = cases[int(line)]
        t0 = time.perf_counter()
        res = ik.solve_path(pos, quats, seed=q, timeout=10.0)
        best = res.paths[0] if res.paths else None
        print(json.dumps({'pose': quats is not None, 'ok': bool(res.success),
                          't': (time.perf_counter() - t0) * 1e3,
                          'travel': best.travel if best else float('nan'),
                          'step': best.max_step if best else float('nan'),
                          'start': (float(np.linalg.norm(best.q[0] - q)) if best
                                    else float('nan'))}), flush=True)


def main() -> None:
    """Start one worker per checkout, hand out the paths in turn and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('checkouts', nargs='+', help='NAME=DIR, the first is the reference')
    parser.add_argument('--paths', type=int, default=80)
    parser.add_argument('--seed', type=int, default=7)
    parser.add_argument('--bundle', default='panda', help='bundle name or directory')
    parser.add_argument('--worker', nargs=4, help=argparse.SUPPRESS)
    add_json_argument(parser)
    args = parser.parse_args()
    if args.worker:
        worker(args.worker[0], int(args.worker[1]), int(args.worker[2]), args.worker[3])
        return
    answers = answers_in_turn(__file__, args.checkouts,
                              [str(args.seed), str(args.paths), args.bundle], args.paths)
    first = next(iter(answers))
    ref = answers[first]
    print(f'# bench/paths_ab.py: {args.paths} paths of {args.bundle} (seed {args.seed}), A B A B')
    print('| checkout | paths | success | time per path (median) | ratio to '
          f'{first} (median) | travel (median) | travel path by path to {first}\'s (mean '
          'ratio; longer / shorter by 1 %) | max step (median) | from the current state '
          '(median) |')
    print('|---|---|---|---|---|---|---|---|---|')
    figures = []
    for spec, name in zip(args.checkouts, answers):
        for pose in (True, False):
            rows = [(a, b) for a, b in zip(answers[name], ref) if a['pose'] == pose]
            # travel path by path, where both solve it (and the reference moves at all)
            both = np.array([a['travel'] / b['travel'] for a, b in rows
                             if a['ok'] and b['ok'] and b['travel'] > 0])
            paired = (f'{both.mean():.3f}; {100 * np.mean(both > 1.01):.0f} / '
                      f'{100 * np.mean(both < 0.99):.0f} %' if len(both) else '—')
            f = {'name': name, **git_commit(spec.partition('=')[2]),
                 'goal': 'pose' if pose else 'position', 'paths': len(rows),
                 'success': float(np.mean([a['ok'] for a, _ in rows])),
                 'time_median_ms': float(np.median([a['t'] for a, _ in rows])),
                 'ratio_median': float(np.median([a['t'] / b['t'] for a, b in rows])),
                 'travel_median_rad': float(np.nanmedian([a['travel'] for a, _ in rows])),
                 'travel_ratio_mean': float(both.mean()) if len(both) else None,
                 'max_step_median_rad': float(np.nanmedian([a['step'] for a, _ in rows])),
                 'start_median_rad': float(np.nanmedian([a['start'] for a, _ in rows]))}
            figures.append(f)
            print(f'| {name} | {f["goal"]} | {100 * f["success"]:.1f} % '
                  f'| {f["time_median_ms"]:.1f} ms | {f["ratio_median"]:.3f} '
                  f'| {f["travel_median_rad"]:.3f} rad | {paired} '
                  f'| {f["max_step_median_rad"]:.3f} rad | {f["start_median_rad"]:.2f} rad |')
    write_json(args.json, 'paths_ab', {'bundle': args.bundle, 'paths': args.paths,
                                       'seed': args.seed, 'checkouts': figures})


if __name__ == '__main__':
    main()
