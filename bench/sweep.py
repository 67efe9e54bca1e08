"""Try sik-build on many example-robot-data arms, as a new user would, with tiny budgets.

For each arm: one ``sik-build --robot ARM`` with a tiny model, a small uniform sample and a
one-minute budget (the frames it inferred, its wall time, the bundle's size and its
self-check), then, for arms of six joints or fewer, on ``--targets`` pose goals (FK of random
configurations, seeded), the branches (distinct solutions once every angle is wrapped to one
turn, as ``bench/arms.py`` counts them) of ours against TRAC-IK's from ``--attempts`` random
seeds: what the arm's limits leave of its branches. (The 2 pi equivalents of periodic joints
are further distinct solutions, of which TRAC-IK's random seeds find many more than the 16 we
return; a redundant arm's solutions are not isolated.) A tiny build is far from a served
bundle's accuracy or speed (``bench/arms.py`` measures those); this shows that each arm loads,
builds, solves and finds the solutions there are.

    python bench/sweep.py --json docs/results/sweep.json        # the default list of arms
    python bench/sweep.py --out /tmp/sweep --arms z1,ur10 --targets 30
"""

import argparse
import contextlib
import json
import os
from pathlib import Path
import subprocess
import sys
import time

os.environ.setdefault('OMP_NUM_THREADS', '1')

import numpy as np  # noqa: E402

from sik_ros import SelectiveIK  # noqa: E402

from arms import branches  # noqa: E402,I100 (bench/arms.py, beside this script)
from peers import TracIK  # noqa: E402
from report import add_json_argument, write_json  # noqa: E402 (bench/report.py)

ARMS = ('ur3_gripper,ur10,z1,b1_z1,bravo7_gripper,talos_arm,so101,tiago,pr2,baxter,'
        'anymal_kinova')


@contextlib.contextmanager
def quiet_stdout():
    """The process's standard output (file descriptor 1, C++ included) muted for a while."""
    sys.stdout.flush()
    saved = os.dup(1)
    with open(os.devnull, 'w') as null:
        os.dup2(null.fileno(), 1)
        try:
            yield
        finally:
            os.dup2(saved, 1)
            os.close(saved)


def tiny_build(arm, out, args):
    """Build ``arm`` into ``out`` (unless there); its wall time [s] and the robot line printed.

    The wall time is kept beside the bundle (``<out>.sweep.json``) for later runs.
    """
    record = out.with_name(out.name + '.sweep.json')
    if (out / 'bundle.json').exists():
        return (json.loads(record.read_text()).get('build_s') if record.exists() else None), ''
    t0 = time.perf_counter()
    run = subprocess.run([sys.executable, '-m', 'sik_ros.cli.build', '--robot', arm, '--out',
                          str(out), '--time', str(args.time), '--rows', str(args.rows),
                          '--preset', 'tiny', '--check-targets', str(args.targets), '--quiet'],
                         capture_output=True, text=True)
    if run.returncode != 0:
        raise RuntimeError(f'{arm}: sik-build exited {run.returncode}: '
                           f'{run.stderr.strip()[-300:]}')
    robot_line = next((ln for ln in run.stdout.splitlines() if ln.startswith('robot ')), '')
    wall = time.perf_counter() - t0
    record.write_text(json.dumps({'build_s': wall}))
    return wall, robot_line


def sweep_arm(arm, args):
    """One arm: build, self-check, pose goals against TRAC-IK; a dict of figures."""
    out = Path(args.out) / arm
    wall, _ = tiny_build(arm, out, args)
    ik = SelectiveIK.load(out)
    robot = ik.robot
    check = json.loads((out / 'bundle.json').read_text())['self_check']
    size = sum(f.stat().st_size for f in out.iterdir() if f.is_file())
    rng = np.random.default_rng(args.seed)
    with quiet_stdout():  # KDL's URDF parser prints warnings about root links there
        tracik = TracIK(robot)
    ours, peer, reached = [], [], []
    # a redundant arm's solutions are not isolated: no branches to count
    for q in rng.uniform(robot.lower, robot.upper, (args.targets * (robot.dof <= 6), robot.dof)):
        p, quat = robot.fk(q)
        res = ik.solve(p, quat, num_solutions=16)
        ours.append(branches([s.q for s in res.solutions if s.converged]))
        found = [s for ok, s in (tracik.solve(p, quat, rng.uniform(robot.lower, robot.upper))
                                 for _ in range(args.attempts)) if ok]
        peer.append(branches(found))
        reached.append(bool(found))
    row = {'arm': arm, 'dof': robot.dof, 'base': robot.base_frame, 'tip': robot.tip_frame,
           'periodic': int(robot.periodic.sum()), 'build_s': wall, 'bundle_mb': size / 1e6,
           'check': check}
    if ours:
        row.update(ours_mean=float(np.mean(ours)), peer_mean=float(np.mean(peer)),
                   at_least_peer=float(np.mean(np.array(ours) >= np.array(peer))),
                   peer_reached=float(np.mean(reached)))
    return row


def main():
    """Parse arguments, sweep the arms, print a table (and ``--json``)."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--out', default='bundles_sweep', help='folder for the tiny bundles')
    parser.add_argument('--arms', default=ARMS, help='comma-separated example-robot-data names')
    parser.add_argument('--time', type=float, default=60.0, help='sik-build budget [s]')
    parser.add_argument('--rows', type=int, default=200_000, help='uniform samples per arm')
    parser.add_argument('--targets', type=int, default=50, help='targets per check')
    parser.add_argument('--attempts', type=int, default=200, help='TRAC-IK seeds per target')
    parser.add_argument('--seed', type=int, default=2024)
    add_json_argument(parser)
    args = parser.parse_args()
    rows = []
    print('| arm | joints (periodic) | base → tip | build [s] | bundle [MB] | self-check '
          'position: success, distinct median | pose: success, distinct median | pose '
          'branches, ours / TRAC-IK (mean) | ours ≥ TRAC-IK |')
    print('|---|---|---|---|---|---|---|---|---|')
    for arm in args.arms.split(','):
        try:
            r = sweep_arm(arm, args)
        except Exception as exc:  # noqa: B902 (an arm that fails is a finding, not the end)
            print(f'| {arm} | failed: {" ".join(str(exc).split())[:300]} |||||||', flush=True)
            rows.append({'arm': arm, 'error': str(exc)})
            continue
        rows.append(r)
        c = r['check']
        build = '—' if r['build_s'] is None else f'{r["build_s"]:.0f}'
        print(f'| {arm} | {r["dof"]} ({r["periodic"]}) | {r["base"]} → {r["tip"]} | {build} | '
              f'{r["bundle_mb"]:.1f} | {100 * c["position"]["success"]:.0f} %, '
              f'{c["position"]["distinct_median"]:.0f} | {100 * c["pose"]["success"]:.0f} %, '
              f'{c["pose"]["distinct_median"]:.0f} | ' + (
                  f'{r["ours_mean"]:.2f} / {r["peer_mean"]:.2f} | '
                  f'{100 * r["at_least_peer"]:.0f} % |' if 'ours_mean' in r else '— | — |'),
              flush=True)
    write_json(args.json, 'sweep', {'time_s': args.time, 'rows': args.rows,
                                    'targets': args.targets, 'attempts': args.attempts,
                                    'seed': args.seed, 'arms': rows})


if __name__ == '__main__':
    main()
