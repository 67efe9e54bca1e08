"""Benchmark SelectiveIK against the solvers users loop over today, in the same run.

Targets are drawn uniformly in joint space (FK of random configurations, seeded). For each
target, our solver returns up to 16 ranked solutions; each peer is then called from random seeds
until it has as many distinct solutions as ours (or an attempt cap), and the per-target time ratio
ours / peer is reported. Peers: TRAC-IK (pytracik) for pose goals; damped least squares on
Pinocchio Jacobians for position goals (TRAC-IK has no position-only mode; its full-pose figures
are shown beside for reference). Also: raw (unrefined) decoder errors, and an obstacle case.

    python bench/solve.py --targets 1000 --json docs/results/solve.json   # docs/benchmarks.md
    python bench/solve.py --targets 50 --quick                            # a smoke run
"""

import argparse
import json
import os
import platform
import time

os.environ.setdefault('OMP_NUM_THREADS', '1')

import numpy as np  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402
import torch  # noqa: E402

from sik_ros.kinematics.collision import CollisionChecker, Obstacle  # noqa: E402
from sik_ros.solver import SelectiveIK  # noqa: E402
from sik_ros.solver.candidates import (oriented_postures, starting_postures,  # noqa: E402
                                       table_candidates)
from sik_ros.solver.codec import decode  # noqa: E402
from sik_ros.solver.context import Goal  # noqa: E402
from sik_ros.solver.refine import errors  # noqa: E402

from peers import DLS as PinocchioDLS, TracIK  # noqa: E402,I100 (bench/peers.py)
from report import add_json_argument, write_json  # noqa: E402 (bench/report.py)

DISTINCT = 0.5  # rad, L2 between joint vectors


def distinct_count(qs, position_goal: bool) -> int:
    """Greedy count of solutions at least DISTINCT apart (positions: the last joint ignored)."""
    cols = slice(0, -1) if position_goal else slice(None)
    kept = []
    for q in qs:
        if all(np.linalg.norm(q[cols] - k[cols]) >= DISTINCT for k in kept):
            kept.append(q)
    return len(kept)


def peer_time_to(count, solve_once, rng, robot, position_goal, max_attempts):
    """Seconds a peer needs to reach ``count`` distinct solutions from random seeds."""
    found, attempts = [], 0
    t0 = time.perf_counter()
    while distinct_count(found, position_goal) < count and attempts < max_attempts:
        ok, q = solve_once(rng.uniform(robot.lower, robot.upper))
        attempts += 1
        if ok:
            found.append(q)
    return time.perf_counter() - t0, distinct_count(found, position_goal), attempts


def bench_goal(ik, goal, positions, quats, peers, args):
    """Run ours and the peers on every target of one goal kind; print a table.

    Returns:
        the figures of the table (times [ms], errors [m] and [rad]).
    """
    robot = ik.robot
    position_goal = goal == 'position'
    rng = np.random.default_rng(11)
    rows = {'ok': [], 'n': [], 't': [], 'raw': [], 'raw_o': [], 'raw_best': [], 'cand': [],
            'cand_o': [], 'or': [], 'or_o': [], 'cached': []}
    peer_rows = {name: {'t': [], 'reached': [], 'ratio': []} for name in peers}
    for i, p in enumerate(positions):
        quat = None if position_goal else quats[i]
        res = ik.solve(p, quat, num_solutions=16)
        qs = [s.q for s in res.solutions if s.converged]
        n = distinct_count(qs, position_goal)
        rows['ok'].append(res.success)
        rows['n'].append(n)
        rows['t'].append(res.elapsed)
        raw = ik.solve(p, quat, num_solutions=10, refine=False)
        rows['raw'] += [s.position_error for s in raw.solutions]
        rot = None if quat is None else Rotation.from_quat(quat).as_matrix()
        target = Goal(np.asarray(p, float), rot)
        z = table_candidates(ik.context, target, None, 16)[0]
        perr, oerr = errors(ik.context, decode(ik.context, target, z), target)
        rows['cand'] += perr.tolist()
        rows['cand_o'] += oerr.tolist()
        if position_goal and ik.models[goal].table.postures is not None:
            # where refinement starts: the table's decoded postures at the cells' centres
            z, table_rows = table_candidates(ik.context, target, None, 16, True, 0)
            q_start = starting_postures(ik.context, target, z, table_rows)
            rows['cached'] += errors(ik.context, q_start, target)[0].tolist()
        if not position_goal:
            q_or = oriented_postures(ik.context, target, ik.config.oriented_candidates)
            if len(q_or):
                perr, oerr = errors(ik.context, q_or, target)
                rows['or'] += perr.tolist()
                rows['or_o'] += oerr.tolist()
        rows['raw_o'] += [s.orientation_error for s in raw.solutions]
        rows['raw_best'].append(raw.solutions[0].position_error)
        for name, solve_once in peers.items():
            if n == 0:
                continue
            t, reached, _ = peer_time_to(n, lambda q0: solve_once(p, quats[i], q0), rng, robot,
                                         position_goal, args.max_attempts)
            peer_rows[name]['t'].append(t)
            peer_rows[name]['reached'].append(reached >= n)
            peer_rows[name]['ratio'].append(res.elapsed / t)
    t = np.array(rows['t']) * 1e3
    print(f'\n## {goal} goals, {len(positions)} targets, num_solutions=16')
    print(f'ours: success {100 * np.mean(rows["ok"]):.1f} %, distinct exact solutions median '
          f'{np.median(rows["n"]):.0f} (p10 {np.percentile(rows["n"], 10):.0f}), time per '
          f'call median {np.median(t):.2f} ms, p95 {np.percentile(t, 95):.2f} ms')
    raw_line = (f'ours raw (refine=False, 10 per target): mean distance error '
                f'{100 * np.mean(rows["raw"]):.2f} cm, best-ranked '
                f'{100 * np.mean(rows["raw_best"]):.2f} cm')
    if not position_goal:
        raw_line += f', mean orientation error {np.degrees(np.mean(rows["raw_o"])):.2f} deg'
    print(raw_line)
    cand_line = (f'every candidate of a refined call decoded at the goal (no selection): mean '
                 f'distance error {100 * np.mean(rows["cand"]):.2f} cm')
    if not position_goal:
        cand_line += f', orientation {np.degrees(np.mean(rows["cand_o"])):.2f} deg'
    print(cand_line)
    if rows['cached']:
        print(f'the same candidates from the table\'s decoded postures (cell centres, where '
              f'refinement starts): mean distance error {100 * np.mean(rows["cached"]):.2f} cm')
    if rows['or']:
        print(f'oriented candidates (position model, closed-form last joint, no selection): '
              f'mean distance error {100 * np.mean(rows["or"]):.2f} cm, orientation '
              f'{np.degrees(np.mean(rows["or_o"])):.2f} deg')
    print('| peer (to the same number of distinct solutions) | median time [ms] | reached | '
          'median ratio ours/peer | p90 ratio | median ratio where reached |')
    print('|---|---|---|---|---|---|')
    mean = (lambda v: float(np.mean(v)) if len(v) else float('nan'))  # noqa: E731
    out = {'targets': len(positions), 'success': float(np.mean(rows['ok'])),
           'distinct_median': float(np.median(rows['n'])),
           'distinct_p10': float(np.percentile(rows['n'], 10)),
           'time_median_ms': float(np.median(t)), 'time_p95_ms': float(np.percentile(t, 95)),
           'raw_mean_m': mean(rows['raw']), 'raw_best_m': mean(rows['raw_best']),
           'raw_orientation_mean_rad': None if position_goal else mean(rows['raw_o']),
           'candidates_mean_m': mean(rows['cand']),
           'candidates_orientation_mean_rad': None if position_goal else mean(rows['cand_o']),
           'cached_postures_mean_m': mean(rows['cached']) if rows['cached'] else None,
           'oriented_mean_m': mean(rows['or']) if rows['or'] else None,
           'oriented_orientation_mean_rad': mean(rows['or_o']) if rows['or'] else None,
           'peers': []}
    for name, pr in peer_rows.items():
        if not pr['t']:
            continue
        reached = np.array(pr['reached'], dtype=bool)
        ratio = np.array(pr['ratio'])
        out['peers'].append({
            'name': name, 'time_median_ms': 1e3 * float(np.median(pr['t'])),
            'reached': float(np.mean(reached)), 'ratio_median': float(np.median(ratio)),
            'ratio_p90': float(np.percentile(ratio, 90)),
            'ratio_median_reached': (float(np.median(ratio[reached])) if reached.any()
                                     else float('nan'))})
        print(f'| {name} | {1e3 * np.median(pr["t"]):.2f} | {100 * np.mean(reached):.1f} % '
              f'| {np.median(ratio):.3f} | {np.percentile(ratio, 90):.3f} '
              f'| {out["peers"][-1]["ratio_median_reached"]:.3f} |')
    return out


def single_solution_time(ik, tracik, robot, positions, quats):
    """One pose solution per target, ours and TRAC-IK's, in turn target by target.

    Ours unseeded and seeded, TRAC-IK from the same random seed. Returns medians [ms] and the
    median of the per-target ratios, and the success rates.
    """
    rng = np.random.default_rng(5)
    t = {'ours': [], 'ours seeded': [], 'trac-ik': []}
    ok = {k: 0 for k in t}
    for p, q in zip(positions, quats):
        seed = rng.uniform(robot.lower, robot.upper)
        for name, call in (('ours', lambda: ik.solve(p, q, num_solutions=1).success),
                           ('ours seeded',
                            lambda: ik.solve(p, q, num_solutions=1, seed=seed).success),
                           ('trac-ik', lambda: tracik.solve(p, q, seed)[0])):
            t0 = time.perf_counter()
            good = call()
            t[name].append(time.perf_counter() - t0)
            ok[name] += bool(good)
    t = {k: np.array(v) for k, v in t.items()}
    return ({k: 1e3 * float(np.median(v)) for k, v in t.items()},
            {k: float(np.median(t[k] / t['trac-ik'])) for k in ('ours', 'ours seeded')},
            {k: 100 * v / len(positions) for k, v in ok.items()})


def obstacle_case(ik):
    """A box in front of the arm that the best unconstrained solution hits; its figures."""
    target = np.array([0.45, 0.0, 0.25])
    free = ik.solve(target, num_solutions=16)
    checker = CollisionChecker(ik.robot)
    best = free.solutions[0]
    # a box between the base and the target, at the height of the best posture's elbow
    from sik_ros.kinematics.chain import chain_forward
    _, _, origins, _ = chain_forward(ik.robot.chain, best.q[None], frames=True)
    elbow = origins[0, 3]
    box = Obstacle('box', (0.15, 0.3, 0.15), tuple(float(v) for v in elbow))
    before = float(checker.clearance(best.q[None], [box])[0])
    res = ik.solve(target, num_solutions=16, obstacles=[box])
    n_free = sum(1 for s in res.solutions if s.converged and not s.in_collision)
    print('\n## obstacle case')
    print(f'target {target.tolist()}, box 0.15 x 0.3 x 0.15 m at the unconstrained best '
          f"solution's elbow {np.round(elbow, 3).tolist()}")
    print(f'unconstrained best solution: clearance {before:+.3f} m (collides: {before <= 0})')
    print(f'with the obstacle: {len(res.solutions)} solutions, {n_free} exact and '
          f'collision-free; best clearance {res.solutions[0].min_obstacle_distance:+.3f} m, '
          f'error {res.solutions[0].position_error * 1e3:.3f} mm, '
          f'{res.elapsed * 1e3:.1f} ms')
    best = res.solutions[0]
    return {'target': target, 'box_size': (0.15, 0.3, 0.15), 'box_position': elbow,
            'clearance_unconstrained_m': before, 'solutions': len(res.solutions),
            'exact_free': n_free, 'clearance_m': best.min_obstacle_distance,
            'error_m': best.position_error, 'time_ms': 1e3 * res.elapsed}


def main():
    """Entry point."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--targets', type=int, default=1000)
    parser.add_argument('--bundle', default='panda')
    parser.add_argument('--max-attempts', type=int, default=300,
                        help='peer attempts per target before giving up')
    parser.add_argument('--goals', default='position,pose')
    parser.add_argument('--quick', action='store_true', help='alias for --targets 50')
    parser.add_argument('--config', default='{}',
                        help='SolverConfig fields to change, as JSON, e.g. '
                        '\'{"give_up_after": 10}\'')
    add_json_argument(parser)
    args = parser.parse_args()
    if args.quick:
        args.targets = min(args.targets, 50)
    torch.set_num_threads(1)
    ik = SelectiveIK.load(args.bundle).with_config(**json.loads(args.config))
    robot = ik.robot
    rng = np.random.default_rng(2024)
    q = rng.uniform(robot.lower, robot.upper, size=(args.targets, robot.dof))
    positions, quats = robot.fk_batch(q)
    tracik = TracIK(robot)
    dls = PinocchioDLS(robot)
    print(f'# bench/solve.py: {platform.processor() or platform.machine()}, '
          f'{os.cpu_count()} cores, torch threads 1, {args.targets} targets uniform in joint '
          f'space (seed 2024), bundle {args.bundle}, solver config changes {args.config}')
    results = {'targets': args.targets, 'seed': 2024, 'bundle': args.bundle,
               'config': json.loads(args.config), 'max_attempts': args.max_attempts}
    if 'pose' in ik.goals:
        med, ratio, ok = single_solution_time(ik, tracik, robot, positions, quats)
        results['single'] = {'time_median_ms': med, 'ratio_median': ratio,
                             'success': {k: v / 100 for k, v in ok.items()}}
        print(f'single pose solution (num_solutions=1), in turn per target: TRAC-IK (random '
              f'seed) median {med["trac-ik"]:.3f} ms, success {ok["trac-ik"]:.1f} %; ours '
              f'{med["ours"]:.3f} ms (ratio {ratio["ours"]:.2f}), seeded '
              f'{med["ours seeded"]:.3f} ms (ratio {ratio["ours seeded"]:.2f}), success '
              f'{ok["ours"]:.1f} / {ok["ours seeded"]:.1f} %')
    goals = args.goals.split(',')
    if 'position' in goals and 'position' in ik.goals:
        results['position'] = bench_goal(ik, 'position', positions, quats, {
            'DLS on Pinocchio Jacobians (position)': lambda p, _q, q0: dls.solve(p, q0),
            'TRAC-IK on the full pose (reference)': lambda p, qt, q0: tracik.solve(p, qt, q0),
        }, args)
    if 'pose' in goals and 'pose' in ik.goals:
        results['pose'] = bench_goal(ik, 'pose', positions, quats, {
            'TRAC-IK (pose)': lambda p, qt, q0: tracik.solve(p, qt, q0),
        }, args)
    results['obstacle'] = obstacle_case(ik)
    write_json(args.json, 'solve', results)


if __name__ == '__main__':
    main()
