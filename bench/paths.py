"""Benchmark Cartesian paths: SelectiveIK.solve_path against the seeded solvers users chain today.

200 paths on the Panda: straight lines and circular arcs (radius 5-15 cm) of 10-60 cm with 20-60
waypoints, the tool orientation held (pose paths) or free (position paths). Each path is drawn
from a random configuration and kept only if a damped least squares continuation from it
reaches every waypoint with steps of at most 0.3 rad (a continuous joint path exists) from a
start clear of self-collision; it is
then solved from a *different* random current state. Peers in the same run, path by path:
TRAC-IK seeded with the previous waypoint's solution (the first with the current state; 5 ms
per waypoint; the MoveIt way) for pose paths, a damped least squares continuation from the
current state for position paths. Whole-path success means every waypoint exact and no joint
step above 0.3 rad. Printed by length (below and from 30 cm): the median of the per-path time
ratios and the ratio of the total times (the mean time per path's), the joint travel of both
on the paths both solve, and an obstacle case.

    python bench/paths.py --paths 200 --json docs/results/paths.json
"""

import argparse
import os
import time

os.environ.setdefault('OMP_NUM_THREADS', '1')

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402
import torch  # noqa: E402

from sik_ros import Obstacle, SelectiveIK  # noqa: E402
from sik_ros.kinematics.chain import chain_forward  # noqa: E402
from sik_ros.kinematics.robot import find_frame  # noqa: E402

from peers import TracIK  # noqa: E402,I100 (bench/peers.py)
from report import add_json_argument, write_json  # noqa: E402 (bench/report.py)

STEP = 0.3  # rad


class Continuation:
    """Damped least squares on Pinocchio, each waypoint started from the previous solution."""

    def __init__(self, robot, tol=1e-4, rot_tol=1e-3, iters=100, damping=1e-3):
        self.robot, self.tol, self.rot_tol, self.iters = robot, tol, rot_tol, iters
        self.damping = damping
        self.model, self.data = robot.model, robot.model.createData()
        self.fid = find_frame(robot.model, robot.tip_frame)

    def solve(self, p, rot, q):
        """One waypoint from ``q``: (converged, q); ``rot`` None for a position goal."""
        rows = 3 if rot is None else 6
        for _ in range(self.iters):
            pin.framesForwardKinematics(self.model, self.data, q)
            pl = self.data.oMf[self.fid]
            err = p - pl.translation
            if rot is not None:
                err = np.concatenate([err, pin.log3(rot @ pl.rotation.T)])
            if np.linalg.norm(err[:3]) < self.tol and (
                    rot is None or np.linalg.norm(err[3:]) < self.rot_tol):
                return True, q
            jac = pin.computeFrameJacobian(self.model, self.data, q, self.fid,
                                           pin.LOCAL_WORLD_ALIGNED)[:rows]
            dq = jac.T @ np.linalg.solve(jac @ jac.T + self.damping ** 2 * np.eye(rows), err)
            dq *= min(1.0, 0.2 / max(np.abs(dq).max(), 1e-12))
            q = np.clip(q + dq, self.robot.lower, self.robot.upper)
        return False, q

    def path(self, pos, rots, q):
        """The whole path from ``q``: (success, joint path so far)."""
        out = []
        for i, p in enumerate(pos):
            ok, q2 = self.solve(p, None if rots is None else rots[i], q)
            if not ok or (out and np.abs(q2 - out[-1]).max() > STEP):
                return False, np.array(out)
            out.append(q2)
            q = q2
        return True, np.array(out)


class SeededTracIK(TracIK):
    """TRAC-IK, each waypoint seeded with the previous waypoint's solution (5 ms each)."""

    def path(self, pos, quats, q):
        """The whole path from ``q``: (success, joint path so far)."""
        out = []
        for p, quat in zip(pos, quats):
            ok, q2 = self.solve(p, quat, q)
            if not ok or (out and np.abs(q2 - out[-1]).max() > STEP):
                return False, np.array(out)
            out.append(q2)
            q = q2
        return True, np.array(out)


def make_path(rng, robot, cont, checker):
    """A feasible path: waypoints (N, 3), rotations (N, 3, 3), quaternions, length, kind."""
    while True:
        q0 = rng.uniform(robot.lower, robot.upper)
        if checker.self_collision(q0[None])[0]:
            continue  # a path an arm can follow starts clear of itself
        p0, r0 = chain_forward(robot.chain, q0[None])
        p0, r0 = p0[0], r0[0]
        length = rng.uniform(0.10, 0.60)
        n = int(rng.integers(20, 61))
        if rng.random() < 0.5:
            d = rng.normal(size=3)
            pos = p0 + np.linspace(0, length, n)[:, None] * d / np.linalg.norm(d)
            kind = 'line'
        else:
            radius = rng.uniform(0.05, 0.15)
            a, b = np.linalg.qr(rng.normal(size=(3, 2)))[0].T
            angle = np.linspace(0, min(length / radius, 2 * np.pi), n)
            centre = p0 - radius * a
            pos = centre + radius * (np.cos(angle)[:, None] * a + np.sin(angle)[:, None] * b)
            length = radius * angle[-1]
            kind = 'arc'
        rots = np.repeat(r0[None], n, 0)
        ok, _ = cont.path(pos, rots, q0)
        if ok:
            return pos, rots, Rotation.from_matrix(rots).as_quat(), length, kind


def travel(q):
    """Joint travel of a path [rad]."""
    return float(np.linalg.norm(np.diff(q, axis=0), axis=1).sum()) if len(q) > 1 else 0.0


def main() -> None:
    """Run the paths and print the tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--paths', type=int, default=200)
    parser.add_argument('--seed', type=int, default=2024)
    parser.add_argument('--num-paths', type=int, default=4,
                        help='ranked paths asked of ours (the peers give one)')
    add_json_argument(parser)
    args = parser.parse_args()
    torch.set_num_threads(1)
    ik = SelectiveIK.load('panda')
    robot = ik.robot
    cont, trac = Continuation(robot), SeededTracIK(robot)
    rng = np.random.default_rng(args.seed)
    rows = []
    for k in range(args.paths):
        pos, rots, quats, length, kind = make_path(rng, robot, cont, ik.checker)
        pose = k % 2 == 0
        q_cur = rng.uniform(robot.lower, robot.upper)
        t0 = time.perf_counter()
        res = ik.solve_path(pos, quats if pose else None, seed=q_cur, timeout=10.0,
                            num_paths=args.num_paths)
        t_ours = time.perf_counter() - t0
        t0 = time.perf_counter()
        if pose:
            ok_peer, q_peer = trac.path(pos, quats, q_cur)
        else:
            ok_peer, q_peer = cont.path(pos, None, q_cur)
        t_peer = time.perf_counter() - t0
        best = res.paths[0] if res.paths else None
        rows.append({'pose': pose, 'kind': kind, 'long': length >= 0.30, 'ok': res.success,
                     'ok_peer': ok_peer, 't': t_ours, 't_peer': t_peer,
                     'step': best.max_step if best is not None else np.nan,
                     'travel': best.travel if best is not None else np.nan,
                     'travel_peer': travel(q_peer), 'n': len(pos)})
    print(f'# bench/paths.py: {args.paths} Panda paths (seed {args.seed}), lines and arcs of '
          f'10-60 cm, 20-60 waypoints, solved from a random current state; success = every '
          f'waypoint exact and no joint step above {STEP} rad; ours asked for '
          f'{args.num_paths} ranked path(s)')
    print('| paths | length | n | ours: success | peer | peer: success | time ours / peer '
          '(median, ms) | ratio (median) | ratio of the total times | travel ours / peer where '
          'both succeed (median, rad) |')
    print('|---|---|---|---|---|---|---|---|---|---|')
    groups, overall = [], []
    for pose in (True, False):
        for long in (False, True):
            sel = [r for r in rows if r['pose'] == pose and r['long'] == long]
            if not sel:
                continue
            both = [r for r in sel if r['ok'] and r['ok_peer']]
            peer = 'TRAC-IK seeded' if pose else 'DLS continuation'
            groups.append({
                'goal': 'pose' if pose else 'position', 'long': long, 'paths': len(sel),
                'peer': peer, 'success': float(np.mean([r['ok'] for r in sel])),
                'peer_success': float(np.mean([r['ok_peer'] for r in sel])),
                'time_median_ms': 1e3 * float(np.median([r['t'] for r in sel])),
                'peer_time_median_ms': 1e3 * float(np.median([r['t_peer'] for r in sel])),
                'ratio_median': float(np.median([r['t'] / r['t_peer'] for r in sel])),
                'ratio_total': sum(r['t'] for r in sel) / sum(r['t_peer'] for r in sel),
                'both': len(both),
                'travel_median_rad': (float(np.median([r['travel'] for r in both]))
                                      if both else None),
                'peer_travel_median_rad': (float(np.median([r['travel_peer'] for r in both]))
                                           if both else None)})
            print(f"| {'pose' if pose else 'position'} | {'>= 30 cm' if long else '< 30 cm'} "
                  f"| {len(sel)} | {100 * np.mean([r['ok'] for r in sel]):.1f} % | {peer} "
                  f"| {100 * np.mean([r['ok_peer'] for r in sel]):.1f} % "
                  f"| {1e3 * np.median([r['t'] for r in sel]):.1f} / "
                  f"{1e3 * np.median([r['t_peer'] for r in sel]):.1f} "
                  f"| {np.median([r['t'] / r['t_peer'] for r in sel]):.2f} "
                  f"| {sum(r['t'] for r in sel) / sum(r['t_peer'] for r in sel):.2f} "
                  f"| {np.median([r['travel'] for r in both]) if both else float('nan'):.2f} / "
                  f"{np.median([r['travel_peer'] for r in both]) if both else float('nan'):.2f} |")
    for pose in (True, False):
        sel = [r for r in rows if r['pose'] == pose]
        ours = 100 * np.mean([r['ok'] for r in sel])
        peer = 100 * np.mean([r['ok_peer'] for r in sel])
        overall.append({'goal': 'pose' if pose else 'position', 'paths': len(sel),
                        'success': ours / 100, 'peer_success': peer / 100,
                        'max_step_median_rad': float(np.nanmedian([r['step'] for r in sel]))})
        print(f"{'pose' if pose else 'position'} paths overall: ours {ours:.1f} %, peer "
              f"{peer:.1f} %, max step of ours (median) "
              f"{np.nanmedian([r['step'] for r in sel]):.3f} rad")
    obstacle = obstacle_case(ik)
    write_json(args.json, 'paths', {'paths': args.paths, 'seed': args.seed,
                                    'num_paths': args.num_paths, 'step_rad': STEP,
                                    'groups': groups, 'overall': overall,
                                    'obstacle': obstacle})


def obstacle_case(ik) -> dict:
    """A box next to a line that the first-ranked unconstrained path hits; its figures."""
    q0 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
    p0, quat = ik.fk(q0)
    pos = p0 + np.linspace(0, 0.2, 20)[:, None] * [0.0, 1.0, 0.0]
    quats = np.repeat(quat[None], 20, 0)
    free = ik.solve_path(pos, quats, seed=q0)
    _, _, origins, _ = chain_forward(ik.robot.chain, free.paths[0].q[10:11], frames=True)
    box = Obstacle('box', (0.12, 0.12, 0.12), tuple(origins[0, 3]))
    hit = ik.checker.clearance(free.paths[0].q, [box]).min()
    t0 = time.perf_counter()
    res = ik.solve_path(pos, quats, seed=q0, obstacles=[box])
    took = time.perf_counter() - t0
    print(f'obstacle case: a 12 cm box at the elbow of the unconstrained best path (clearance '
          f'{hit:+.3f} m); with it: success {res.success}, clearance '
          f'{res.paths[0].min_obstacle_distance if res.paths else float("nan"):+.3f} m, '
          f'{1e3 * took:.0f} ms')
    return {'box_size': 0.12, 'clearance_unconstrained_m': float(hit),
            'success': bool(res.success),
            'clearance_m': res.paths[0].min_obstacle_distance if res.paths else None,
            'time_ms': 1e3 * took}


if __name__ == '__main__':
    main()
