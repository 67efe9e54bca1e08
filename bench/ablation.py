r"""What the learned model contributes: the solver with its starts from one source at a time.

For each arm (a bundle) and goal kind, targets uniform in joint space (FK of seeded random
configurations); for every target each source gives the same number of starting postures
(``--starts``), which the solver refines as usual (restarts when none converges, the self-motion
walk of pose goals on arms with more than six joints, ranking, 16 solutions asked):

- ``index table``: the learned posture indices of the position model's table near the goal,
  decoded (position goals: the table's decoded postures; pose goals: the indices whose rows had
  the goal's orientation, their last joint turned towards it);
- ``pose model``: the pose model's indices near the goal (and its sweep of a 1-d index over
  every branch code) decoded at the goal pose (pose goals);
- ``seed table``: the nearest collected configurations alone (the dataset's rows nearest the
  goal: by tip position for position goals, by tip pose for pose goals, as the solver's seed
  table; far apart in joint space);
- ``random``: uniform random configurations;
- ``shipped``: the solver as it ships (its own mix of starts), for reference;
- ``shipped + pose model K`` (``--pose-candidates K``, pose goals): the shipped solver with K
  of the pose model's decoded candidates among its starts (``SolverConfig.pose_candidates``),
  the A/B of whether the pose model pays for itself by default.

The sources answer each target in turn, the order rotating from target to target (paired, in one
process). Printed per arm, goal kind and source: success, distinct exact solutions (mean and
median of those asked), branches (distinct once every angle is wrapped to one turn, mean), time
per call (median, mean). ``--json`` writes every figure.

    python bench/ablation.py --arm panda=sik_ros/bundles/panda:data/panda30 \\
        --arm ur5=bundles/ur5:bundles/ur5.build/dataset --targets 100 \\
        --json docs/results/ablation.json
"""

import argparse
from dataclasses import replace
import os
import sys
import time

os.environ.setdefault('OMP_NUM_THREADS', '1')

import numpy as np  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402
import torch  # noqa: E402

from sik_ros import SelectiveIK  # noqa: E402
from sik_ros.kinematics.chain import chain_forward  # noqa: E402
from sik_ros.solver import pipeline  # noqa: E402
from sik_ros.solver.batch import Candidates  # noqa: E402
from sik_ros.solver.candidates import (oriented_postures, starting_postures,  # noqa: E402
                                       table_candidates)
from sik_ros.solver.context import Goal, POSE  # noqa: E402
from sik_ros.tables.dataset import Dataset  # noqa: E402
from sik_ros.tables.point_sets import farthest_point_subset  # noqa: E402
from sik_ros.tables.seed_table import SeedTable  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from arms import branches  # noqa: E402,I100 (bench/arms.py, beside this script)
from report import add_json_argument, write_json  # noqa: E402 (bench/report.py)

SOURCES = {'position': ('index table', 'seed table', 'random', 'shipped'),
           'pose': ('index table', 'pose model', 'seed table', 'random', 'shipped')}


class Starts:
    """The starting postures of one source, for the solver's first stage."""

    def __init__(self, ik: SelectiveIK, seeds: SeedTable, count: int):
        self.ik, self.seeds, self.count = ik, seeds, count
        robot = ik.robot
        tips, _ = chain_forward(robot.chain, seeds.q)
        self.tree = cKDTree(tips)
        self.source = 'shipped'

    def __call__(self, ctx, goal: Goal, num, q_seed, refined, seeded=False) -> Candidates:
        """Starts of the current source (the solver's ``initial_postures``)."""
        n, robot = self.count, self.ik.robot
        if self.source == 'index table' and goal.kind == POSE:
            q = oriented_postures(ctx, goal, n)
        elif self.source in ('index table', 'pose model'):
            cfg = replace(ctx.config, num_candidates=n, pose_candidates=n,
                          candidates_per_solution=1e-9)
            wide = replace(ctx, config=cfg)
            z, rows = table_candidates(wide, goal, None, num, True)
            q = starting_postures(wide, goal, z[:n], rows[:n])
        elif self.source == 'seed table' and goal.kind == POSE:
            q = self.seeds.starts(goal.position, goal.quaternion, n)
        elif self.source == 'seed table':
            _, near = self.tree.query(goal.position, k=100)
            q = self.seeds.q[near]
            q = q[farthest_point_subset(q, n)]
        else:
            rng = np.random.default_rng(int(1e6 * abs(goal.position[0])) + 7)
            q = rng.uniform(robot.lower, robot.upper, (n, robot.dof))
        latent = ctx.models[goal.kind].table.indices.shape[1]
        inf = np.full(len(q), np.inf)
        return Candidates(q, np.full((len(q), latent), np.nan), inf, np.zeros(len(q)),
                          np.zeros(len(q), dtype=bool))


def run_arm(name: str, bundle: str, data: str, targets: int, num: int, starts: int,
            seed: int, seed_rows: int, pose_candidates: int = 0,
            goals=('position', 'pose')) -> dict:
    """Every goal kind and source of one arm: the figures."""
    torch.set_num_threads(1)
    shipped = SelectiveIK.load(bundle)
    # only the source's starts: no seed-table or random branch starts of the solver's own
    ablated = shipped.with_config(seed_starts=0, branch_restarts=0)
    robot = shipped.robot
    seeds = SeedTable.build(robot, Dataset.load(data, robot), rows=seed_rows, seed=seed)
    source = Starts(shipped, seeds, starts)
    original = pipeline.initial_postures

    def initial(ctx, goal, num_, q_seed, refined, seeded=False):
        if source.source == 'shipped':
            return original(ctx, goal, num_, q_seed, refined, seeded)
        return source(ctx, goal, num_, q_seed, refined, seeded)
    pipeline.initial_postures = initial
    rng = np.random.default_rng(seed)
    q = rng.uniform(robot.lower, robot.upper, (targets, robot.dof))
    out = {}
    try:
        for kind in [k for k in goals if k in shipped.goals]:
            names = SOURCES[kind]
            if kind == 'pose' and pose_candidates:
                names = names + (f'shipped + pose model {pose_candidates}',)
                with_pose = shipped.with_config(pose_candidates=pose_candidates)
            rec = {s: {'ok': [], 'distinct': [], 'branches': [], 'ms': []} for s in names}
            for t, qi in enumerate(q):
                p, quat = shipped.fk(qi)
                order = names[t % len(names):] + names[:t % len(names)]
                for s in order:
                    source.source = s
                    ik = shipped if s == 'shipped' else ablated
                    if s.startswith('shipped + '):
                        source.source, ik = 'shipped', with_pose
                    t0 = time.perf_counter()
                    res = ik.solve(p, quat if kind == 'pose' else None, num_solutions=num)
                    ms = 1e3 * (time.perf_counter() - t0)
                    exact = [x.q for x in res.solutions if x.converged]
                    r = rec[s]
                    r['ok'].append(bool(res.success))
                    r['distinct'].append(len(exact))
                    r['branches'].append(branches(exact))
                    r['ms'].append(ms)
            out[kind] = {s: summary(r) for s, r in rec.items()}
    finally:
        pipeline.initial_postures = original
    return out


def summary(r: dict) -> dict:
    """Success, distinct solutions, branches and time of one source."""
    return {'targets': len(r['ok']), 'success': float(np.mean(r['ok'])),
            'distinct_mean': float(np.mean(r['distinct'])),
            'distinct_median': float(np.median(r['distinct'])),
            'branches_mean': float(np.mean(r['branches'])),
            'ms_median': float(np.median(r['ms'])), 'ms_mean': float(np.mean(r['ms']))}


def table(results: dict, starts: int, num: int) -> str:
    """The figures as a markdown table."""
    lines = [f'| arm | goal | starts ({starts} each) | success | distinct of {num} (mean, '
             f'median) | branches (mean) | ms per call (median, mean) |',
             '|---|---|---|---|---|---|---|']
    for arm, kinds in results.items():
        for kind, rows in kinds.items():
            for s, r in rows.items():
                lines.append(f'| {arm} | {kind} | {s} | {100 * r["success"]:.1f} % | '
                             f'{r["distinct_mean"]:.1f}, {r["distinct_median"]:.0f} | '
                             f'{r["branches_mean"]:.1f} | {r["ms_median"]:.2f}, '
                             f'{r["ms_mean"]:.2f} |')
    return '\n'.join(lines)


def main() -> int:
    """Entry point."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--arm', action='append', required=True,
                    help='NAME=BUNDLE:DATASET (the dataset the seed-table starts come from)')
    ap.add_argument('--targets', type=int, default=100)
    ap.add_argument('--num', type=int, default=16, help='solutions asked per call')
    ap.add_argument('--starts', type=int, default=32, help='starting postures per source')
    ap.add_argument('--seed-rows', type=int, default=500_000,
                    help='dataset rows the seed-table source keeps')
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--pose-candidates', type=int, default=0,
                    help='also the shipped solver with this many pose-model candidates')
    ap.add_argument('--goals', default='position,pose', help='goal kinds, comma-separated')
    add_json_argument(ap)
    a = ap.parse_args()
    results = {}
    for spec in a.arm:
        name, _, rest = spec.partition('=')
        bundle, _, data = rest.partition(':')
        if not (name and bundle and data):
            print(f'ablation: --arm wants NAME=BUNDLE:DATASET; got {spec!r}', file=sys.stderr)
            return 2
        t0 = time.perf_counter()
        results[name] = run_arm(name, bundle, data, a.targets, a.num, a.starts, a.seed,
                                a.seed_rows, a.pose_candidates, a.goals.split(','))
        print(f'{name}: {time.perf_counter() - t0:.0f} s', flush=True)
    print(table(results, a.starts, a.num))
    write_json(a.json, 'ablation', {'args': {k: v for k, v in vars(a).items() if k != 'json'},
                                    'arms': results})
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
