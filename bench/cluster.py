"""A reachability map on 1 and 2 workers: local processes against a local Ray cluster.

The same map (``--voxel``, ``--orientations``, ``-n`` solutions per goal, no timeout, so that
each goal's answer does not depend on the machine's load) is built into a fresh folder by
local worker processes (``build_reach_map(workers=W)``) and by the actors of a local Ray cluster
of W CPUs (``RayExecutor(workers=W)``), for W in ``--workers``, in turn (A B A B over
``--repeats`` rounds). Prints each run's pose goals per second (the median round), the speed-up
of 2 workers over 1, the cluster's start (the first map on it includes its actors loading the
bundle: timed apart), and whether every map equals the first one goal for goal.

Usage: ``python bench/cluster.py [--bundle panda] [--voxel 0.2] [--orientations 16] [-n 16]
[--workers 1,2] [--repeats 2] [--json PATH]``.
"""

import argparse
import os
from pathlib import Path
import shutil
import tempfile
import time

import numpy as np
from report import add_json_argument, write_json

from sik_ros import SelectiveIK
from sik_ros.solver.cluster import RayExecutor
from sik_ros.solver.reach_map import build_reach_map, load_reach_map, ReachSettings


def timed_map(ik, settings, folder: Path, **how):
    """Seconds to build the map into an empty ``folder``, and the map."""
    shutil.rmtree(folder, ignore_errors=True)
    t = time.perf_counter()
    path = build_reach_map(ik, folder, settings, **how)
    return time.perf_counter() - t, load_reach_map(path)


def main():
    """Build the maps, print the figures."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('--bundle', default='panda')
    p.add_argument('--voxel', type=float, default=0.2)
    p.add_argument('--orientations', type=int, default=16)
    p.add_argument('-n', '--num-solutions', type=int, default=16)
    p.add_argument('--workers', default='1,2')
    p.add_argument('--repeats', type=int, default=2)
    add_json_argument(p)
    args = p.parse_args()
    ik = SelectiveIK.load(args.bundle)
    ik.warm_up()
    settings = ReachSettings(voxel=args.voxel, orientations=args.orientations,
                             num_solutions=args.num_solutions)
    counts = [int(w) for w in args.workers.split(',')]
    root = Path(tempfile.mkdtemp(prefix='sik_cluster_'))
    load0 = os.getloadavg()[0]
    rows, reference, same = [], None, True
    try:
        for w in counts:
            t = time.perf_counter()
            with RayExecutor(workers=w) as ex:
                start_s = time.perf_counter() - t
                first_s, _ = timed_map(ik, settings, root / 'warm', executor=ex)
                times = {'processes': [], 'ray': []}
                for _ in range(args.repeats):  # A B A B
                    for kind in ('processes', 'ray'):
                        how = dict(executor=ex) if kind == 'ray' else dict(workers=w)
                        seconds, data = timed_map(ik, settings, root / kind, **how)
                        times[kind].append(seconds)
                        if reference is None:
                            reference = data
                        same &= all(np.array_equal(reference[k], data[k])
                                    for k in ('success', 'families', 'centers'))
            goals = reference['success'].size
            for kind, seconds in times.items():
                rows.append(dict(workers=w, kind=kind, seconds=float(np.median(seconds)),
                                 goals_per_s=goals / float(np.median(seconds)),
                                 rounds=seconds))
            rows[-1].update(cluster_start_s=start_s, first_map_s=first_s)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    figures = dict(bundle=args.bundle, voxel=args.voxel, orientations=args.orientations,
                   num_solutions=args.num_solutions, voxels=len(reference['centers']),
                   goals=int(reference['success'].size),
                   reached=float(reference['success'].mean()), runs=rows, same_maps=same,
                   load_average=[load0, os.getloadavg()[0]])
    for kind in ('processes', 'ray'):
        by = {r['workers']: r['goals_per_s'] for r in rows if r['kind'] == kind}
        if 1 in by and 2 in by:
            figures[f'{kind}_speedup_2_over_1'] = by[2] / by[1]
    print(f'{figures["voxels"]} voxels x {args.orientations} orientations = '
          f'{figures["goals"]} pose goals, {figures["reached"]:.1%} reached, '
          f'{args.num_solutions} solutions asked')
    for r in rows:
        extra = (f'  (cluster start {r["cluster_start_s"]:.1f} s, first map with the actors '
                 f'loading {r["first_map_s"]:.1f} s)' if 'cluster_start_s' in r else '')
        print(f'{r["kind"]:>10} x{r["workers"]}: {r["seconds"]:7.2f} s  '
              f'{r["goals_per_s"]:7.0f} goals/s{extra}')
    for key in ('processes_speedup_2_over_1', 'ray_speedup_2_over_1'):
        if key in figures:
            print(f'{key}: {figures[key]:.2f}')
    print(f'every map the same, goal for goal: {same}')
    write_json(args.json, 'cluster', figures)


if __name__ == '__main__':
    main()
