"""Fingerprint the solver's answers, to show that a change of code left them as they were.

For each arm, targets are drawn uniformly in joint space (FK of random configurations, seeded);
each target is solved four ways with no deadline (so the answers do not depend on the machine's
speed): 16 solutions unseeded, one solution from a seed, raw (``refine=False``) from a seed, and
one obstacle near the target. The solutions are written to an ``.npz`` file and their digest
(SHA-256 of the joint values rounded to 1e-9 rad, with the counts and tiers) is printed per arm
and goal kind. ``--compare`` reads another run's file and prints, per arm and goal kind, whether
the answers are equal, and the largest joint difference.

    python bench/answers.py --arm panda=panda --arm ur5=BUNDLE_DIR --targets 300 --out a.npz
    python bench/answers.py ... --out b.npz --compare a.npz
"""

import argparse
import hashlib
import os
import sys

os.environ.setdefault('OMP_NUM_THREADS', '1')

import numpy as np  # noqa: E402

from sik_ros.kinematics.collision import Obstacle  # noqa: E402
from sik_ros.solver import SelectiveIK  # noqa: E402

#: The four ways each target is solved: (name, keyword arguments, uses a seed).
CASES = (('multi', dict(num_solutions=16), False),
         ('single_seeded', dict(num_solutions=1), True),
         ('raw_seeded', dict(num_solutions=10, refine=False), True),
         ('obstacle', dict(num_solutions=8), False))


def answers(ik: SelectiveIK, goal: str, targets: int, seed: int):
    """Solutions of every case at ``targets`` targets, as arrays keyed ``case/field``."""
    rng = np.random.default_rng(seed)
    lo, hi = ik.robot.lower, ik.robot.upper
    out = {}
    rows = {case: ([], [], []) for case, _, _ in CASES}
    for _ in range(targets):
        q_goal = rng.uniform(lo, hi)
        q_seed = np.clip(q_goal + rng.normal(0.0, 0.3, q_goal.shape), lo, hi)
        pos, quat = ik.fk(q_goal)
        rot = quat if goal == 'pose' else None
        ball = Obstacle('sphere', (0.04,), position=tuple(pos + [0.0, 0.0, 0.12]))
        for case, kw, seeded in CASES:
            res = ik.solve(pos, rot, seed=q_seed if seeded else None,
                           obstacles=[ball] if case == 'obstacle' else (), timeout=None, **kw)
            qs, counts, tiers = rows[case]
            counts.append(len(res.solutions))
            qs.extend(s.q for s in res.solutions)
            tiers.extend(s.tier for s in res.solutions)
    for case, (qs, counts, tiers) in rows.items():
        out[f'{case}/q'] = np.asarray(qs, float).reshape(-1, ik.robot.dof)
        out[f'{case}/count'] = np.asarray(counts, int)
        out[f'{case}/tier'] = np.asarray(tiers, int)
    return out


def digest(arrays) -> str:
    """SHA-256 (first 16 hex digits) of rounded joint values, counts and tiers."""
    h = hashlib.sha256()
    for key in sorted(arrays):
        a = arrays[key]
        h.update(key.encode())
        h.update(np.round(a, 9).tobytes() if a.dtype.kind == 'f' else a.astype(np.int64).tobytes())
    return h.hexdigest()[:16]


def compare(mine, theirs, prefix: str) -> str:
    """Equal, or where the answers of one arm and goal kind differ."""
    notes = []
    for case, _, _ in CASES:
        key = f'{prefix}/{case}'
        a_count, b_count = mine[f'{key}/count'], theirs[f'{key}/count']
        if not np.array_equal(a_count, b_count):
            notes.append(f'{case}: counts differ at {int((a_count != b_count).sum())} targets')
            continue
        if not np.array_equal(mine[f'{key}/tier'], theirs[f'{key}/tier']):
            notes.append(f'{case}: tiers differ')
        dq = np.abs(mine[f'{key}/q'] - theirs[f'{key}/q'])
        if dq.size and dq.max() > 0:
            notes.append(f'{case}: largest joint difference {dq.max():.2e} rad')
    return 'equal' if not notes else '; '.join(notes)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--arm', action='append', required=True, metavar='NAME=BUNDLE',
                   help='an arm and its bundle (a bundled name or a directory); repeatable')
    p.add_argument('--targets', type=int, default=300, help='targets per goal kind')
    p.add_argument('--seed', type=int, default=0)
    p.add_argument('--out', required=True, help='write the solutions to this .npz file')
    p.add_argument('--compare', help='an earlier run\'s .npz file to compare with')
    args = p.parse_args(argv)
    every = {}
    theirs = np.load(args.compare) if args.compare else None
    for spec in args.arm:
        name, _, bundle = spec.partition('=')
        ik = SelectiveIK.load(bundle or name)
        for goal in ik.goals:
            arrays = answers(ik, goal, args.targets, args.seed)
            line = f'{name:8s} {goal:8s} {digest(arrays)}  ' + ' '.join(
                f'{k.split("/")[0]}={len(v)}' for k, v in arrays.items() if k.endswith('/q'))
            every.update({f'{name}/{goal}/{k}': v for k, v in arrays.items()})
            if theirs is not None:
                line += '  ' + compare(every, theirs, f'{name}/{goal}')
            print(line, flush=True)
    tmp = args.out + '.tmp.npz'
    np.savez_compressed(tmp, **every)
    os.replace(tmp, args.out)
    return 0


if __name__ == '__main__':
    sys.exit(main())
