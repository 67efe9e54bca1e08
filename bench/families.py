"""Posture families: how many of a pose's families our answers cover, against references.

- **Panda** (``--panda-poses`` per seed of ``--seeds``, ``--near-singular`` of them drawn near
  a singularity): the pose's families are the connected pieces of its self-motion within the
  limits, swept over joint 7 on a fine grid (``--q7-samples``): the analytic solver
  ``frankik`` (He and Liu's geometric IK, up to 4 solutions per value of joint 7), completed
  by a numerical sweep with joint 7 held (``--held-starts`` random starts per value, and the
  solutions at the neighbouring value continued: frankik leaves out a branch of joint 4).
  Solutions at neighbouring values within 0.3 rad are linked; where one has no neighbour, the
  interval is halved (five times at most), and two curves that end in one finest interval
  meet there (a fold). A piece along which joint 7 hardly moves is no piece to a sweep over
  it: verified paths (``--no-paths`` leaves them out) follow the curve from every family's
  ends, each point checked by Pinocchio's FK, and join the families they reach. Ours (16
  asked; with the family search, the default, and without it, each pose both ways in turn)
  cover a family when one of our exact solutions lies within 0.25 rad of a sample of it;
  TRAC-IK restarts from random seeds for the same wall time as ours are counted alike. Our
  solutions on no family of the reference count apart. Also: whether our ``family`` labels
  agree with the reference's (pairs of our solutions on one reference family labelled alike,
  and on two labelled apart), and whether the first answers come from as many families.
- **Arms of six joints** (``--arm-bundle``, several comma-separated; ``--arm-poses`` per seed
  of ``--arm-seeds``): the pose's branches (exact solutions with every angle wrapped to one
  turn, 0.1 rad apart) known from the union of ours and of ``--restarts`` TRAC-IK restarts per
  pose; the share ours return, and the poses where ours return all. A pose drawn within 2e-4
  of a singularity (the Jacobian's least singular value) is counted apart: its exact
  solutions form a continuum, on which solutions 0.1 rad apart are no branches.

Every solution is checked by the solver's FK within the default tolerances (0.1 mm, 1 mrad).
Prints the figures; ``--json`` writes them for ``bench/render.py``.
"""

import argparse
import os
import sys
import time
from typing import Dict, List, Tuple

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from peers import TracIK  # noqa: E402
from report import add_json_argument, write_json  # noqa: E402

from sik_ros.kernels.families import branch_labels  # noqa: E402
from sik_ros.solver import SelectiveIK  # noqa: E402

#: Exactness of every counted solution (the solver's default tolerances).
POS_TOL, ROT_TOL = 1e-4, 1e-3
#: A solution lies on a reference family when this close to one of its samples [rad].
ON_FAMILY = 0.25
#: Reference samples at neighbouring values of joint 7 closer than this are linked [rad].
LINK = 0.3
#: Times an interval of joint 7 is halved where a solution has no neighbour within LINK.
DEPTH = 5
#: Two curves that end in one finest interval meet there only this far from every limit [rad].
EDGE = 0.01
#: Step of a verified path between the reference's families [rad], and most steps each way.
PATH_STEP = 0.05
PATH_STEPS = 400
#: Uniform draws among which the poses near a singularity are chosen.
SINGULAR_DRAWS = 2000
#: Two solutions at one value of joint 7 closer than this are one [rad].
SAME_SAMPLE = 0.01
#: An arm of six joints: a pose whose drawn configuration's least singular value is below
#: this has a continuum of exact solutions (0.5 rad along it move the tip less than the
#: position tolerance), no isolated branches to count.
CONTINUUM = 2e-4
#: Branches of an arm of six joints: wrapped solutions closer than this are one [rad].
SAME_BRANCH = 0.1


def exact(ik: SelectiveIK, q: np.ndarray, position: np.ndarray, rot: np.ndarray) -> bool:
    """Whether ``q`` reaches the pose within the tolerances (the solver's own FK)."""
    p, r = ik.robot.fk_rot(q[None])
    dr = r[0].T @ rot
    angle = np.arccos(np.clip((np.trace(dr) - 1) / 2, -1, 1))
    return np.linalg.norm(p[0] - position) <= POS_TOL and angle <= ROT_TOL


def homogeneous(p: np.ndarray, r: np.ndarray) -> np.ndarray:
    """A 4 x 4 transform from a position (3,) and a rotation (3, 3)."""
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = r, p
    return t


class HeldSweep:
    """A numerical sweep of joint 7, completing frankik's.

    At each value, joint 7 held, the other six are solved from the solutions at the
    neighbouring values (the sweep continued) and from random starts (damped least squares,
    the solver's compiled kernel, 60 iterations); the exact, distinct solutions are kept.
    frankik leaves out a branch of joint 4 (solutions with joint 4 above about -0.47 rad).
    """

    def __init__(self, ik: SelectiveIK, starts: int):
        from sik_ros.solver.refine import kernel_settings
        self.robot, self.cfg = ik.robot, ik.config
        self.settings = kernel_settings(ik.config, 60, 0, False, False, True)
        self.rng = np.random.default_rng(0)
        self.starts = starts

    def aim(self, p: np.ndarray, r: np.ndarray) -> None:
        """The pose of the next sweep."""
        self.pos, self.rot = np.ascontiguousarray(p), np.ascontiguousarray(r)

    def solutions(self, q7: float, hint: np.ndarray, draw: bool) -> List[np.ndarray]:
        """Distinct exact solutions within the limits with joint 7 held at ``q7``.

        Refined from ``hint`` (K, 7) (joint 7 set to ``q7``: the sweep continued) and, with
        ``draw``, from random starts.
        """
        from sik_ros.kernels.dls import refine_rows
        robot = self.robot
        lower, upper = robot.lower.copy(), robot.upper.copy()
        lower[6] = upper[6] = q7
        q = np.concatenate([np.reshape(hint, (-1, 7)),
                            self.rng.uniform(lower, upper, (self.starts if draw else 0, 7))])
        if not len(q):
            return []
        q[:, 6] = q7
        m = len(q)
        perr, oerr, status = np.empty(m), np.empty(m), np.empty(m, dtype=np.int8)
        reals, ints = self.settings
        refine_rows(robot.frames, lower, upper, np.asarray(robot.periodic, dtype=bool), q,
                    self.pos, self.rot, reals.copy(), ints, perr, oerr, status)
        out: List[np.ndarray] = []
        for i in np.flatnonzero((perr <= POS_TOL) & (oerr <= ROT_TOL)):
            if all(np.linalg.norm(q[i] - k) > SAME_SAMPLE for k in out):
                out.append(q[i].copy())
        return out


class Frankik:
    """The analytic reference for the Panda: ``frankik.ik_full`` swept over joint 7."""

    def __init__(self, ik: SelectiveIK, samples: int, held_starts: int = 0,
                 paths: bool = False):
        import frankik
        self.fk, self.ik_full = frankik.fk, frankik.ik_full
        self.lower, self.upper = ik.robot.lower, ik.robot.upper
        self.q7 = np.linspace(self.lower[6], self.upper[6], samples)
        q = np.array([0.1, -0.4, 0.2, -2.0, 0.3, 1.5, 0.6])
        ours = homogeneous(*[a[0] for a in ik.robot.fk_rot(q[None])])
        # the solver's tip in the frame of frankik's fk (a fixed offset), and the pose its ik
        # takes: fk's frame less its hand offset
        self.offset = np.linalg.inv(self.fk(q)) @ ours
        self.hand = frankik.FrankaKinematics.FrankaHandTCPOffset
        self.held = HeldSweep(ik, held_starts) if held_starts > 0 else None
        self.robot, self.paths = ik.robot, paths

    def _at(self, goal: np.ndarray, q7: float, hint: np.ndarray, draw: bool) -> np.ndarray:
        """The solutions within the limits at one value of joint 7 (K, 7).

        frankik's, and the numerical sweep's (:class:`HeldSweep`, from ``hint``, the
        solutions at neighbouring values, and with ``draw`` random starts) that none of
        frankik's lies near.
        """
        sol = self.ik_full(goal, None, float(q7))
        keep = [q for q in sol if np.isfinite(q).all() and np.all(q >= self.lower - 1e-9)
                and np.all(q <= self.upper + 1e-9)]
        if self.held is not None:
            for q in self.held.solutions(q7, hint, draw):
                if all(np.linalg.norm(q - k) > SAME_SAMPLE for k in keep):
                    keep.append(q)
        return np.array(keep).reshape(-1, 7)

    def families(self, p: np.ndarray, r: np.ndarray):
        """The reference's samples (S, 7) and their family labels (S,), and the sweep's time.

        Solutions at neighbouring values of joint 7 within :data:`LINK` are linked. Where a
        solution at one value has none within :data:`LINK` at the next (the curve moves fast
        near a singularity, or ends), the interval is halved, down to :data:`DEPTH` times, and
        the halves linked alike; two curves that end in the same finest interval, within
        :data:`LINK` of each other and clear of the limits, meet there (a fold of the
        self-motion in joint 7: one family).
        """
        goal = homogeneous(p, r) @ np.linalg.inv(self.offset) @ np.linalg.inv(self.hand)
        if self.held is not None:
            self.held.aim(p, r)
        t0 = time.perf_counter()
        rows: List[np.ndarray] = []
        parent: List[int] = []

        def add(q7, hint=(), draw=False):
            sol = self._at(goal, q7, np.array([rows[i] for i in hint]), draw)
            first = len(rows)
            rows.extend(sol)
            parent.extend(range(first, first + len(sol)))
            return list(range(first, first + len(sol)))

        def root(i):
            while parent[i] != i:
                parent[i] = parent[parent[i]]
                i = parent[i]
            return i

        def union(i, j):
            ri, rj = root(i), root(j)
            parent[max(ri, rj)] = min(ri, rj)

        def clear(i):
            q = rows[i]
            return bool(np.all(q > self.lower + EDGE) and np.all(q < self.upper - EDGE))

        def meet(ends):
            for x, i in enumerate(ends):
                for j in ends[x + 1:]:
                    if clear(i) and clear(j) and np.linalg.norm(rows[i] - rows[j]) < LINK:
                        union(i, j)

        def connect(va, a, vb, b, depth):
            linked_a, linked_b = set(), set()
            for i in a:
                for j in b:
                    if np.linalg.norm(rows[i] - rows[j]) < LINK:
                        union(i, j)
                        linked_a.add(i)
                        linked_b.add(j)
            ends_a = [i for i in a if i not in linked_a]
            ends_b = [j for j in b if j not in linked_b]
            if not ends_a and not ends_b:
                return
            if depth < DEPTH:
                vm = (va + vb) / 2
                m = add(vm, a + b)
                connect(va, a, vm, m, depth + 1)
                connect(vm, m, vb, b, depth + 1)
            else:
                meet(ends_a)
                meet(ends_b)

        grid = []
        for v in self.q7:
            grid.append(add(v, grid[-1] if grid else (), True))
        for k in range(len(grid) - 1):
            connect(self.q7[k], grid[k], self.q7[k + 1], grid[k + 1], 0)
        elapsed = time.perf_counter() - t0
        if not rows:
            return np.empty((0, 7)), np.empty(0, dtype=int), elapsed
        labels = np.array([root(i) for i in range(len(rows))])
        labels = np.unique(labels, return_inverse=True)[1]
        if self.paths:
            return (*joined_by_paths(self.robot, p, r, np.array(rows), labels), elapsed)
        return np.array(rows), labels, elapsed


def rotation_angle(r: np.ndarray) -> float:
    """The angle of a rotation matrix [rad]."""
    return float(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1)))


def verified(robot, q: np.ndarray, p: np.ndarray, r: np.ndarray) -> bool:
    """Whether ``q`` lies within the limits and reaches the pose by Pinocchio's own FK."""
    tip = robot.pin_placement(q)
    return bool(np.all(q >= robot.lower) and np.all(q <= robot.upper)) and \
        np.linalg.norm(tip.translation - p) <= POS_TOL and \
        rotation_angle(tip.rotation.T @ r) <= ROT_TOL


def pose_error(robot, q: np.ndarray, p: np.ndarray, r: np.ndarray):
    """The tip's error (6,) (position, rotation vector in the base frame) and Jacobian."""
    tp, tr, jac = robot.jacobian_batch(q[None])
    dr = r @ tr[0].T
    angle = rotation_angle(dr)
    axis = np.array([dr[2, 1] - dr[1, 2], dr[0, 2] - dr[2, 0], dr[1, 0] - dr[0, 1]])
    w = axis * (angle / (2 * np.sin(angle)) if angle > 1e-9 else 0.5)
    return np.concatenate([p - tp[0], w]), jac[0]


def joined_by_paths(robot, p: np.ndarray, r: np.ndarray, ref_q: np.ndarray,
                    labels: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """The reference's labels, families joined where a verified path of solutions joins them.

    A sweep of joint 7 sees a piece of the self-motion along which joint 7 hardly moves (the
    other six move at one value of it) as no piece at all, and parts the families it joins.
    From both ends (in joint 7) of every family, the curve is followed both ways within the
    limits: points :data:`PATH_STEP` apart (null vector of the Jacobian, then damped least
    squares back onto the pose), each verified by Pinocchio's FK and the limits, none more
    than two steps from the last; a family whose sample the path passes within
    :data:`PATH_STEP` is joined to the end's. An end near a limit is followed too (the
    verification stops a path that leaves the limits): a curve can run along a limit, within
    a few milliradians of it, and on to another family.

    Returns:
        the samples (the reference's and the paths' points) and their labels.
    """
    parent = np.arange(labels.max() + 1)
    points, owner = [], []

    def root(i):
        while parent[i] != i:
            i = parent[i]
        return i
    for f in range(labels.max() + 1):
        rows = np.flatnonzero(labels == f)
        for e in (rows[np.argmin(ref_q[rows, 6])], rows[np.argmax(ref_q[rows, 6])]):
            for way in (1.0, -1.0):
                x, heading = ref_q[e].copy(), None
                for _ in range(PATH_STEPS):
                    _, jac = pose_error(robot, x, p, r)
                    v = np.linalg.svd(jac)[2][-1]
                    v *= way if heading is None else np.sign(v @ heading) or 1.0
                    y = x + PATH_STEP * v
                    for _ in range(10):
                        err, jac = pose_error(robot, y, p, r)
                        if np.linalg.norm(err[:3]) < POS_TOL / 10 and \
                                np.linalg.norm(err[3:]) < ROT_TOL / 10:
                            break
                        y = y + jac.T @ np.linalg.solve(jac @ jac.T + 1e-10 * np.eye(6), err)
                    if not verified(robot, y, p, r) or np.linalg.norm(y - x) > 2 * PATH_STEP:
                        break
                    heading, x = v, y
                    points.append(y)
                    owner.append(f)
                    near = labels[np.linalg.norm(ref_q - x, axis=1) < PATH_STEP]
                    for g in np.unique(near):
                        a, b = root(f), root(int(g))
                        parent[max(a, b)] = min(a, b)
    q = np.concatenate([ref_q, np.reshape(points, (-1, ref_q.shape[1]))])
    joined = np.array([root(int(f)) for f in np.concatenate([labels, owner]).astype(int)])
    return q, np.unique(joined, return_inverse=True)[1]


def on_family(q: np.ndarray, ref_q: np.ndarray, ref_label: np.ndarray) -> int:
    """The reference family ``q`` lies on, or -1."""
    if len(ref_q) == 0:
        return -1
    d = np.linalg.norm(ref_q - q, axis=1)
    i = int(np.argmin(d))
    return int(ref_label[i]) if d[i] < ON_FAMILY else -1


def panda_row(ik: SelectiveIK, res, p: np.ndarray, r: np.ndarray, ref_q: np.ndarray,
              ref_label: np.ndarray) -> Dict:
    """One answer's figures against the reference's families (no peer)."""
    known = set(ref_label.tolist())
    ours = [s for s in res.solutions if exact(ik, s.q, p, r)]
    fams = [on_family(s.q, ref_q, ref_label) for s in ours]
    covered = {f for f in fams if f >= 0}
    # labels against the reference, over pairs of our solutions on reference families
    agree = pairs = split = merged = 0
    for i in range(len(ours)):
        for j in range(i + 1, len(ours)):
            if fams[i] < 0 or fams[j] < 0:
                continue
            pairs += 1
            same_ref, same_ours = fams[i] == fams[j], ours[i].family == ours[j].family
            agree += same_ref == same_ours
            split += same_ref and not same_ours
            merged += same_ours and not same_ref
    k = len(covered)
    return {'known': len(known), 'ours': k, 'beyond': sum(f < 0 for f in fams),
            'num_families': res.num_families, 'pairs': pairs, 'agree': agree,
            'split': split, 'merged': merged,
            'first_k': len({f for f in fams[:k] if f >= 0}) == k,
            'time_s': res.elapsed, 'success': res.success}


def panda_summary(rows: List[Dict], q7_samples: int, family_search: bool) -> Dict:
    """The figures of one configuration over the poses of ``rows``."""
    with_ref = [x for x in rows if x['known']]
    known = sum(x['known'] for x in with_ref)
    pairs = max(sum(x['pairs'] for x in rows), 1)
    return {
        'poses': len(rows), 'poses_with_reference': len(with_ref),
        'known_mean': known / max(len(with_ref), 1),
        'coverage': sum(x['ours'] for x in with_ref) / max(known, 1),
        'all_families': float(np.mean([x['ours'] == x['known'] for x in with_ref])),
        'poses_all': int(sum(x['ours'] == x['known'] for x in with_ref)),
        'beyond_mean': float(np.mean([x['beyond'] for x in rows])),
        'peer_coverage': sum(x['peer'] for x in with_ref) / max(known, 1),
        'label_agreement': sum(x['agree'] for x in rows) / pairs,
        'label_split': sum(x['split'] for x in rows) / pairs,
        'label_merged': sum(x['merged'] for x in rows) / pairs,
        'first_k': float(np.mean([x['first_k'] for x in with_ref])),
        'num_families_mean': float(np.mean([x['num_families'] for x in rows])),
        'time_median_ms': float(np.median([x['time_s'] for x in rows]) * 1e3),
        'sweep_median_ms': float(np.median([x['sweep_s'] for x in rows]) * 1e3),
        'q7_samples': q7_samples, 'family_search': family_search,
    }


def pose_draws(ik: SelectiveIK, seed: int, count: int, near: int) -> np.ndarray:
    """Configurations (count, n) whose FK are the poses.

    ``count - near`` drawn uniformly within the limits, then ``near`` near a singularity: the
    ``near`` of :data:`SINGULAR_DRAWS` uniform draws whose Jacobian has the smallest least
    singular value.
    """
    rng = np.random.default_rng(seed)
    robot = ik.robot
    q = rng.uniform(robot.lower, robot.upper, (count - near, robot.dof))
    if near <= 0:
        return q
    pool = rng.uniform(robot.lower, robot.upper, (SINGULAR_DRAWS, robot.dof))
    _, _, jac = robot.jacobian_batch(pool)
    least = np.linalg.svd(jac, compute_uv=False)[:, -1]
    return np.concatenate([q, pool[np.argsort(least)[:near]]])


def panda(args) -> Dict:
    """The Panda against the reference's families, with the family search and without it.

    Each pose is solved both ways in turn (which first alternates per pose), the peer's
    budget the default's (the search's) time; on the poses of each of ``--seeds``.
    """
    ik = SelectiveIK.load('panda')
    ik.solve(*ik.fk(np.zeros(7)), num_solutions=16)  # warm
    variants = [True, False]
    for v in variants:
        ik.configure(family_search=v)
        ik.solve(*ik.fk(np.full(7, 0.1)), num_solutions=16)
    ref = Frankik(ik, args.q7_samples, args.held_starts, not args.no_paths)
    tracik = TracIK(ik.robot)
    rows = {v: [] for v in variants}
    seeds_out = {}
    for seed in [int(x) for x in args.seeds.split(',')]:
        draws = pose_draws(ik, seed, args.panda_poses, args.near_singular)
        peer_seeds = np.random.default_rng(seed + 100)  # the peer's: apart from the poses'
        first = len(rows[True])
        for t, q0 in enumerate(draws):
            pos, quat = ik.fk(q0)
            p, r = ik.robot.fk_rot(q0[None])
            p, r = p[0], r[0]
            ref_q, ref_label, sweep_s = ref.families(p, r)
            answers = {}
            for v in (variants if t % 2 == 0 else variants[::-1]):
                ik.configure(family_search=v)
                answers[v] = ik.solve(pos, quat, num_solutions=16)
            # TRAC-IK from random seeds for the default's wall time
            t_budget, t0 = answers[True].elapsed, time.perf_counter()
            peer = set()
            while time.perf_counter() - t0 < t_budget:
                ok, q = tracik.solve(pos, quat,
                                     peer_seeds.uniform(ik.robot.lower, ik.robot.upper))
                if ok and exact(ik, q, p, r):
                    f = on_family(q, ref_q, ref_label)
                    if f >= 0:
                        peer.add(f)
            near = t >= len(draws) - args.near_singular
            for v in variants:
                row = panda_row(ik, answers[v], p, r, ref_q, ref_label)
                row.update(peer=len(peer), sweep_s=sweep_s, near_singular=near)
                rows[v].append(row)
                print(f'panda seed {seed} pose {t:3d}{" near-singular" if near else ""}'
                      f'{"" if v else " search off"}: reference {row["known"]} families; '
                      f'ours {row["ours"]} (+{row["beyond"]} beyond), num_families '
                      f'{row["num_families"]}, labels {row["agree"]}/{row["pairs"]}, TRAC-IK '
                      f'{len(peer)}; {row["time_s"] * 1e3:.1f} ms, reference '
                      f'{sweep_s * 1e3:.0f} ms', flush=True)
        seeds_out[str(seed)] = {('default' if v else 'off'): panda_summary(
            rows[v][first:], args.q7_samples, v) for v in variants}
    out = {('default' if v else 'off'): panda_summary(rows[v], args.q7_samples, v)
           for v in variants}
    out['near_singular'] = {('default' if v else 'off'): panda_summary(
        [x for x in rows[v] if x['near_singular']], args.q7_samples, v) for v in variants}
    out['seeds'] = seeds_out
    out['time_ratio_median'] = float(np.median(
        [b['time_s'] / a['time_s'] for a, b in zip(rows[False], rows[True])]))
    out['near_singular_poses'] = args.near_singular
    out['held_starts'], out['paths'] = args.held_starts, not args.no_paths
    for seed, o in seeds_out.items():
        for name, x in o.items():
            print(f'panda seed {seed} {name}: coverage {x["coverage"]:.3f}, every family on '
                  f'{x["poses_all"]}/{x["poses_with_reference"]}, time median '
                  f'{x["time_median_ms"]:.2f} ms')
    for name in ('default', 'off'):
        o = out[name]
        shown = [(k, v) for k, v in o.items() if not isinstance(v, dict)]
        print(f'panda {name}: ' + ', '.join(
            f'{k} {v:.3g}' if isinstance(v, float) else f'{k} {v}' for k, v in shown))
        o = out['near_singular'][name]
        print(f'panda {name}, near-singular poses: coverage {o["coverage"]:.3f}, every family '
              f'on {o["poses_all"]}/{o["poses_with_reference"]}')
    print(f'panda: time with the search / without, median of pairs: '
          f'{out["time_ratio_median"]:.2f}')
    return out


def redundant(args) -> Dict:
    """A 7-joint arm with no analytic reference: the search against it off, labels traced.

    Each pose solved with the family search (the default) and without it in turn: success,
    exact solutions, families found, time; and the default's labels against the curves traced
    within the limits from its solutions (``families.traced``): pairs on one curve labelled
    apart (split), pairs of one label on two curves (joined).
    """
    from sik_ros.deadline import NO_DEADLINE
    from sik_ros.kinematics.rotations import quaternion_matrix
    from sik_ros.solver import families
    from sik_ros.solver.context import Goal
    ik = SelectiveIK.load(args.redundant_bundle)
    robot = ik.robot
    variants = {True: ik, False: ik.with_config(family_search=False)}
    for v in variants.values():
        v.solve(*ik.fk((robot.lower + robot.upper) / 2), num_solutions=16)  # warm
    rng = np.random.default_rng(args.seed + 2)
    rows = {True: [], False: []}
    split = joined = pairs = 0
    for t in range(args.redundant_poses):
        pos, quat = ik.fk(rng.uniform(robot.lower, robot.upper))
        for v in ((True, False) if t % 2 == 0 else (False, True)):
            res = variants[v].solve(pos, quat, num_solutions=16)
            exact = [s for s in res.solutions if s.converged]
            rows[v].append((res.success, len(exact), res.num_families, res.elapsed))
            if v and len(exact) > 1:
                goal = Goal(np.asarray(pos, float), quaternion_matrix(quat))
                traced = families.traced(ik.context, np.array([s.q for s in exact]), goal,
                                         NO_DEADLINE)
                for i in range(len(exact)):
                    for j in range(i + 1, len(exact)):
                        ours = exact[i].family == exact[j].family
                        curve = traced[i] == traced[j]
                        split += curve and not ours
                        joined += ours and not curve
                        pairs += 1
    out = {'arm': robot.name, 'dof': robot.dof, 'poses': args.redundant_poses}
    for v, name in ((True, 'default'), (False, 'off')):
        a = np.array(rows[v], dtype=float)
        out[name] = {'success': float(a[:, 0].mean()), 'exact_median': float(np.median(a[:, 1])),
                     'families_mean': float(a[:, 2].mean()),
                     'time_median_ms': float(np.median(a[:, 3]) * 1e3)}
    out['time_ratio_median'] = float(np.median(
        [a[3] / b[3] for a, b in zip(rows[True], rows[False])]))
    out['label_pairs'], out['label_split'], out['label_joined'] = pairs, split, joined
    print(f'{robot.name}: ' + ', '.join(f'{k} {v}' for k, v in out.items()))
    return out


def branches(q: List[np.ndarray], periodic: np.ndarray) -> np.ndarray:
    """Branch labels of solutions (every angle wrapped to one turn)."""
    if not q:
        return np.empty(0, dtype=np.int64)
    return branch_labels(np.ascontiguousarray(q, dtype=float), SAME_BRANCH,
                         np.ones(len(periodic), dtype=bool))


def arm(args, bundle: str) -> Dict:
    """An arm of six joints: our branches against the union with TRAC-IK's restarts.

    ``--arm-poses`` poses for each seed of ``--arm-seeds``. A pose whose drawn configuration
    has a Jacobian's least singular value below :data:`CONTINUUM` is set apart: there the
    exact solutions (within the tolerances) form a continuum, and solutions 0.1 rad apart
    along it are no branches of their own.
    """
    ik = SelectiveIK.load(bundle)
    if args.distinct is not None:
        ik.configure(distinct_threshold=args.distinct)
    robot = ik.robot
    ik.solve(*ik.fk((robot.lower + robot.upper) / 2), num_solutions=16)  # warm
    tracik = TracIK(robot)
    rows = []
    for seed in [int(x) for x in args.arm_seeds.split(',')]:
        rng = np.random.default_rng(seed + 1)
        for t in range(args.arm_poses):
            rows.append(dict(arm_pose(ik, tracik, rng, args.restarts), seed=seed))
            x = rows[-1]
            print(f'{robot.name} seed {seed} {t:3d}: known {x["known"]} branches, ours '
                  f'{x["ours"]}; free of self-collision {x["known_free"]}, ours '
                  f'{x["ours_free"]}; num_families {x["num_families"]}, labels consistent '
                  f'{x["consistent"]}, least singular value {x["sigma_min"]:.1e}'
                  f'{" (a continuum)" if x["continuum"] else ""}, {x["time_s"] * 1e3:.1f} ms',
                  flush=True)
    isolated = [x for x in rows if not x['continuum']]
    cont = [x for x in rows if x['continuum']]
    known = sum(x['known'] for x in isolated)
    out = {'arm': robot.name, 'dof': robot.dof, 'poses': len(isolated),
           'seeds': args.arm_seeds, 'restarts': args.restarts,
           'known_mean': known / max(len(isolated), 1),
           'coverage': sum(x['ours'] for x in isolated) / max(known, 1),
           'all_branches': float(np.mean([x['ours'] == x['known'] for x in isolated])),
           'poses_all': int(sum(x['ours'] == x['known'] for x in isolated)),
           'per_seed': {s: int(sum(x['ours'] == x['known'] for x in isolated
                                   if x['seed'] == int(s)))
                        for s in args.arm_seeds.split(',')},
           'known_free_mean': sum(x['known_free'] for x in isolated) / max(len(isolated), 1),
           'coverage_free': sum(x['ours_free'] for x in isolated) / max(
               sum(x['known_free'] for x in isolated), 1),
           'all_free_branches': float(np.mean([x['ours_free'] == x['known_free']
                                               for x in isolated])),
           'distinct_threshold': ik.config.distinct_threshold,
           'labels_consistent': float(np.mean([x['consistent'] for x in isolated])),
           'first_k': float(np.mean([x['first_k'] for x in isolated])),
           'time_median_ms': float(np.median([x['time_s'] for x in isolated]) * 1e3),
           'continuum_poses': len(cont),
           'continuum': [{k: x[k] for k in ('seed', 'known', 'ours', 'sigma_min')}
                         for x in cont]}
    print(f'{robot.name}: ' + ', '.join(f'{k} {v:.3g}' if isinstance(v, float) else f'{k} {v}'
                                        for k, v in out.items()))
    return out


def arm_pose(ik: SelectiveIK, tracik, rng, restarts: int) -> Dict:
    """One pose of an arm of six joints drawn with ``rng``: ours against the known branches."""
    robot = ik.robot
    q0 = rng.uniform(robot.lower, robot.upper)
    pos, quat = ik.fk(q0)
    p, r = robot.fk_rot(q0[None])
    p, r = p[0], r[0]
    res = ik.solve(pos, quat, num_solutions=16)
    ours = [s.q for s in res.solutions if exact(ik, s.q, p, r)]
    theirs = []
    for _ in range(restarts):
        ok, q = tracik.solve(pos, quat, rng.uniform(robot.lower, robot.upper))
        if ok and exact(ik, q, p, r):
            theirs.append(q)
    labels = branches(ours + theirs, robot.periodic)
    # the branches free of self-collision (the seed table's data holds no others)
    every = ours + theirs
    free = {int(b) for b in set(labels.tolist()) if not ik.context.checker.self_collision(
        every[int(np.flatnonzero(labels == b)[0])][None])[0]}
    found = len(set(labels[:len(ours)].tolist()))
    # our labels: one family per branch
    fam = [s.family for s in res.solutions if exact(ik, s.q, p, r)]
    consistent = all((labels[i] == labels[j]) == (fam[i] == fam[j])
                     for i in range(len(ours)) for j in range(i + 1, len(ours)))
    _, _, jac = robot.jacobian_batch(q0[None])
    sigma = float(np.linalg.svd(jac[0], compute_uv=False)[-1])
    return {'known': len(set(labels.tolist())), 'ours': found, 'consistent': consistent,
            'known_free': len(free), 'ours_free': len(free & set(labels[:len(ours)].tolist())),
            'first_k': len(set(labels[:min(found, len(ours))].tolist())) == found,
            'num_families': res.num_families, 'time_s': res.elapsed, 'sigma_min': sigma,
            'continuum': sigma < CONTINUUM}


def main(argv=None) -> int:
    """Run the comparisons asked for and print (and write) the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--panda-poses', type=int, default=40)
    parser.add_argument('--q7-samples', type=int, default=1200,
                        help='values of joint 7 in frankik\'s sweep')
    parser.add_argument('--held-starts', type=int, default=24,
                        help='random starts per value of joint 7 of the numerical sweep that '
                        'completes frankik\'s (0: frankik alone)')
    parser.add_argument('--no-paths', action='store_true',
                        help='the reference\'s families without the verified paths that join '
                        'them')
    parser.add_argument('--redundant-bundle', default='',
                        help='bundle of another 7-joint arm (no analytic reference)')
    parser.add_argument('--redundant-poses', type=int, default=60)
    parser.add_argument('--arm-bundle', default='',
                        help='bundles of arms of six joints, comma-separated')
    parser.add_argument('--arm-poses', type=int, default=20, help='per seed of --arm-seeds')
    parser.add_argument('--arm-seeds', default='0,1,2',
                        help='the six-joint arms\' sets of poses, one per seed')
    parser.add_argument('--restarts', type=int, default=300,
                        help='TRAC-IK restarts per pose of the six-joint arm')
    parser.add_argument('--distinct', type=float, default=None,
                        help='the six-joint arm\'s distinct_threshold (default: the solver\'s)')
    parser.add_argument('--seeds', default='10,11,12',
                        help='the Panda\'s sets of poses, one per seed')
    parser.add_argument('--near-singular', type=int, default=8,
                        help='of each set\'s poses, those drawn near a singularity')
    parser.add_argument('--seed', type=int, default=0, help='the other 7-joint arm\'s poses')
    add_json_argument(parser)
    args = parser.parse_args(argv)
    results = {'seed': args.seed, 'seeds': args.seeds}
    if args.panda_poses > 0:
        results['panda'] = panda(args)
    if args.redundant_bundle and args.redundant_poses > 0:
        results['redundant'] = redundant(args)
    if args.arm_bundle and args.arm_poses > 0:
        results['arms'] = [arm(args, b) for b in args.arm_bundle.split(',')]
    write_json(args.json, 'families', results)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
