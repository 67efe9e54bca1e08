"""sik-reach's map against TRAC-IK on the same pose goals.

Builds the map (``build_reach_map``, every core), then asks TRAC-IK (pytracik, 5 ms per try,
``--restarts`` tries from random seeds, bench/peers.py) for a sample of its goals: the fraction
of the goals TRAC-IK reaches that the map reaches too, and the time per pose goal of the map
(its wall time over its goals) against TRAC-IK's (per sampled goal, up to its first success).

    python bench/reach.py --voxel 0.05 --orientations 64
"""

import argparse
import os
import tempfile
import time

import numpy as np

from peers import TracIK
from report import add_json_argument, write_json

from sik_ros import SelectiveIK
from sik_ros.solver.reach_map import build_reach_map, load_reach_map, ReachSettings


def main():
    """Build the map, ask TRAC-IK, print the figures."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('--bundle', default='panda')
    p.add_argument('--voxel', type=float, default=0.05)
    p.add_argument('--orientations', type=int, default=64)
    p.add_argument('--solutions', type=int, default=16)
    p.add_argument('--workers', type=int)
    p.add_argument('--sample', type=int, default=1000, help='goals asked of TRAC-IK')
    p.add_argument('--restarts', type=int, default=20, help='TRAC-IK tries per goal')
    add_json_argument(p)
    args = p.parse_args()
    ik = SelectiveIK.load(args.bundle)
    ik.warm_up()
    load0 = os.getloadavg()[0]
    settings = ReachSettings(voxel=args.voxel, orientations=args.orientations,
                             num_solutions=args.solutions)
    with tempfile.TemporaryDirectory() as out:
        t = time.perf_counter()
        data = load_reach_map(build_reach_map(ik, out, settings, args.workers))
        t_map = time.perf_counter() - t
    goals = data['success'].size
    rng = np.random.default_rng(0)
    picks = rng.choice(goals, min(args.sample, goals), replace=False)
    peer = TracIK(ik.robot)
    k = len(data['orientations'])
    theirs, ours, t_peer = [], [], 0.0
    for g in picks:
        v, o = divmod(int(g), k)
        t = time.perf_counter()
        ok = False
        for _ in range(args.restarts):
            ok, _q = peer.solve(data['centers'][v], data['orientations'][o],
                                rng.uniform(ik.robot.lower, ik.robot.upper))
            if ok:
                break
        t_peer += time.perf_counter() - t
        theirs.append(ok)
        ours.append(bool(data['success'][v, o]))
    theirs, ours = np.array(theirs), np.array(ours)
    figures = dict(voxels=len(data['centers']), orientations=k, goals=goals,
                   map_s=t_map, ours_per_goal_ms=1e3 * t_map / goals,
                   sampled=len(picks), tracik_reached=int(theirs.sum()),
                   we_reach_of_those=float(ours[theirs].mean()) if theirs.any() else None,
                   we_reach_they_not=int((ours & ~theirs).sum()),
                   tracik_per_goal_ms=1e3 * t_peer / len(picks),
                   time_ratio=(t_map / goals) / (t_peer / len(picks)),
                   load_average=[load0, os.getloadavg()[0]])
    for key, value in figures.items():
        print(f'{key:>20}: {value}')
    write_json(args.json, 'reach', figures)


if __name__ == '__main__':
    main()
