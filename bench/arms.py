"""Benchmark sik-build bundles of several arms against the solvers users loop over today.

For each arm: the bundle (built by ``sik-build`` into ``--bundles/<arm>`` unless it is there,
the wall time printed), its size, then targets uniform in joint space (FK of random
configurations, seeded) per goal kind: success, distinct exact solutions per call (median,
p10) and time per call; in the same run the peer is called from random seeds until it has as
many distinct solutions as ours (or ``--max-attempts``): damped least squares on Pinocchio for
position goals, TRAC-IK for pose goals. For 6-joint arms at pose goals it also counts branches
(distinct solutions with angles wrapped to one turn), ours (of the 16 returned) against
TRAC-IK's from ``--max-attempts`` random seeds: all of them, and those free of self-collision
(our ranking puts a self-colliding posture behind every free one, 2 pi equivalents included, so
16 solutions may leave it out; TRAC-IK does not check collisions).

    python bench/arms.py --arms panda,ur5,xarm7,kinova,so100 --bundles bundles_bench \
        --json docs/results/arms.json
    python bench/arms.py --arms ur5 --targets 50 --no-build   # a smoke run
"""

import argparse
import json
import os
from pathlib import Path
import subprocess
import sys
import time

os.environ.setdefault('OMP_NUM_THREADS', '1')

import numpy as np  # noqa: E402
import torch  # noqa: E402

from sik_ros import SelectiveIK  # noqa: E402
from sik_ros.learning.checkpoints import load_checkpoint  # noqa: E402
from sik_ros.solver.context import tip_on_last_axis  # noqa: E402
from sik_ros.solver.scores import distinct_mask  # noqa: E402

from peers import DLS, TracIK  # noqa: E402,I100 (bench/peers.py, beside this script)
from report import add_json_argument, write_json  # noqa: E402 (bench/report.py)

DISTINCT = 0.5  # rad, as the solver's distinct_threshold


def distinct(ik, qs, goal):
    """How many of ``qs`` are distinct, by the solver's own rule."""
    if not len(qs):
        return 0
    roll_free = goal == 'position' and tip_on_last_axis(ik.robot)
    return int(distinct_mask(np.asarray(qs), DISTINCT, roll_free).sum())


def branches(qs):
    """Distinct solutions once every joint angle is wrapped to (-pi, pi]."""
    if not len(qs):
        return 0
    w = np.angle(np.exp(1j * np.asarray(qs)))
    kept = []
    for q in w:
        if all(np.linalg.norm(np.angle(np.exp(1j * (q - k)))) >= DISTINCT for k in kept):
            kept.append(q)
    return len(kept)


def peer_until(count, solve_once, rng, ik, goal, max_attempts):
    """Seconds and solutions of a peer from random seeds until ``count`` distinct ones."""
    robot, found, attempts = ik.robot, [], 0
    t0 = time.perf_counter()
    while distinct(ik, found, goal) < count and attempts < max_attempts:
        ok, q = solve_once(rng.uniform(robot.lower, robot.upper))
        attempts += 1
        if ok:
            found.append(q)
    return time.perf_counter() - t0, found


def build(arm, bundles, budget):
    """The bundle of ``arm`` (built with sik-build when missing) and the build's wall time."""
    out = Path(bundles) / arm
    if arm == 'panda' and not out.exists():
        return 'panda', None  # the bundled models (scripts/train_bundled.sh)
    if (out / 'bundle.json').exists():
        return str(out), None
    t0 = time.perf_counter()
    subprocess.run([sys.executable, '-m', 'sik_ros.cli.build', '--robot', arm, '--out',
                    str(out), '--time', str(budget), '--quiet'], check=True)
    return str(out), time.perf_counter() - t0


def training(bundle: Path) -> dict:
    """Each model's training: steps, training time [s], last validation distance error [m]."""
    out = {}
    for goal, files in json.loads((bundle / 'bundle.json').read_text())['models'].items():
        ckpt = load_checkpoint(bundle / files['model'])
        last = ckpt['history'][-1] if ckpt.get('history') else {}
        out[goal] = {'steps': int(ckpt.get('step', 0)),
                     'train_s': float(ckpt.get('elapsed_s', 0.0)),
                     'val_dist_m': last.get('val_dist_mean_m')}
    return out


def bench_arm(arm, args):
    """One arm: bundle, then both goal kinds against the peers; a dict of figures."""
    bundle, wall = build(arm, args.bundles, args.time)
    ik = SelectiveIK.load(bundle)
    robot = ik.robot
    size = sum(f.stat().st_size for f in Path(ik.bundle).iterdir() if f.is_file())
    rng = np.random.default_rng(args.seed)
    q = rng.uniform(robot.lower, robot.upper, (args.targets, robot.dof))
    poses = [robot.fk(qi) for qi in q]
    check = json.loads((Path(ik.bundle) / 'bundle.json').read_text()).get('self_check')
    row = {'arm': arm, 'dof': robot.dof, 'build_s': wall, 'bundle_mb': size / 1e6,
           'self_check': check, 'training': training(Path(ik.bundle))}
    dls, tracik = DLS(robot), TracIK(robot)
    for goal in ('position', 'pose'):
        ok, n, t, ratio, reached = [], [], [], [], []
        ours_b, peer_b, ours_f, peer_f = [], [], [], []  # branches: all, self-collision-free
        prng = np.random.default_rng(args.seed + 1)
        for p, quat in poses:
            res = ik.solve(p, quat if goal == 'pose' else None, num_solutions=16)
            exact = [s.q for s in res.solutions if s.converged]
            ok.append(res.success)
            n.append(distinct(ik, exact, goal))
            t.append(res.elapsed)
            if goal == 'position':
                once = lambda q0, p=p: dls.solve(p, q0)  # noqa: E731
            else:
                once = lambda q0, p=p, quat=quat: tracik.solve(p, quat, q0)  # noqa: E731
            if n[-1]:
                tp, found = peer_until(n[-1], once, prng, ik, goal, args.max_attempts)
                ratio.append(res.elapsed / tp)
                reached.append(distinct(ik, found, goal) >= n[-1])
            if goal == 'pose' and robot.dof == 6:
                ours_b.append(branches(exact))
                ours_f.append(branches([s.q for s in res.solutions
                                        if s.converged and not s.self_collision]))
                found = [s[1] for s in (once(prng.uniform(robot.lower, robot.upper))
                                        for _ in range(args.max_attempts)) if s[0]]
                peer_b.append(branches(found))
                peer_f.append(branches([f for f in found
                                        if not ik.checker.self_collision(f[None])[0]]))
        fig = {'success': float(np.mean(ok)), 'distinct_median': float(np.median(n)),
               'distinct_p10': float(np.percentile(n, 10)),
               'time_median_ms': 1e3 * float(np.median(t)),
               'ratio_median': float(np.median(ratio)) if ratio else float('nan'),
               'peer_reached': float(np.mean(reached)) if reached else float('nan')}
        if ours_b:
            fig.update(branches_median=float(np.median(ours_b)),
                       peer_branches_median=float(np.median(peer_b)),
                       branches_mean=float(np.mean(ours_b)),
                       peer_branches_mean=float(np.mean(peer_b)),
                       free_branches_mean=float(np.mean(ours_f)),
                       peer_free_branches_mean=float(np.mean(peer_f)),
                       free_branches_at_least_peer=float(np.mean(
                           np.array(ours_f) >= np.array(peer_f))))
        row[goal] = fig
    return row


def main() -> None:
    """Run every arm and print a table row each (and ``--json``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--arms', default='panda,ur5,xarm7,kinova,so100')
    parser.add_argument('--bundles', default='bundles_bench')
    parser.add_argument('--time', type=float, default=1800.0, help='sik-build budget [s]')
    parser.add_argument('--targets', type=int, default=300)
    parser.add_argument('--max-attempts', type=int, default=300)
    parser.add_argument('--seed', type=int, default=2024)
    parser.add_argument('--no-build', action='store_true', help='skip arms without a bundle')
    add_json_argument(parser)
    args = parser.parse_args()
    torch.set_num_threads(1)
    print(f'# bench/arms.py: {args.targets} targets per goal kind, seed {args.seed}, peers from '
          f'random seeds up to {args.max_attempts} attempts')
    print('| arm | joints | build [s] | bundle [MB] | goal | success | distinct median (p10) '
          '| time/call [ms] | ratio ours/peer (peer reached) | branches ours / TRAC-IK |')
    print('|---|---|---|---|---|---|---|---|---|---|')
    rows = []
    for arm in args.arms.split(','):
        if args.no_build and arm != 'panda' and not (Path(args.bundles) / arm /
                                                     'bundle.json').exists():
            continue
        row = bench_arm(arm, args)
        rows.append(row)
        for goal in ('position', 'pose'):
            f = row[goal]
            peer = 'DLS' if goal == 'position' else 'TRAC-IK'
            br = (f'{f["branches_median"]:.0f} / {f["peer_branches_median"]:.0f} (mean '
                  f'{f["branches_mean"]:.2f} / {f["peer_branches_mean"]:.2f}; free of '
                  f'self-collision {f["free_branches_mean"]:.2f} / '
                  f'{f["peer_free_branches_mean"]:.2f}, ours >= peer on '
                  f'{100 * f["free_branches_at_least_peer"]:.0f} %)'
                  if 'branches_median' in f else '')
            build_s = '' if row['build_s'] is None else f'{row["build_s"]:.0f}'
            print(f'| {arm} | {row["dof"]} | {build_s} | {row["bundle_mb"]:.1f} | {goal} | '
                  f'{100 * f["success"]:.1f} % | {f["distinct_median"]:.0f} '
                  f'({f["distinct_p10"]:.0f}) | {f["time_median_ms"]:.2f} | '
                  f'{f["ratio_median"]:.3f} vs {peer} ({100 * f["peer_reached"]:.0f} %) '
                  f'| {br} |', flush=True)
    write_json(args.json, 'arms', {'targets': args.targets, 'seed': args.seed,
                                   'max_attempts': args.max_attempts, 'arms': rows})


if __name__ == '__main__':
    main()
