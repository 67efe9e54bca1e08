"""Cartesian paths: joint paths through a sequence of tool poses, without flips.

At the first waypoint (and wherever every track is lost) distinct exact configurations start
*tracks*: the solver's solutions (with the seed's own posture and the 2 pi equivalents of
periodic joints), or at a position waypoint the seed and the table's postures nearest it
followed onto the waypoint (:func:`_starts`); at each
next waypoint every track is continued by refining its last configuration onto the new pose (a
warm start: the posture is kept, the paper's "keep the posture" strategy). The candidates of
consecutive waypoints form a ladder graph; an edge is allowed when no joint moves more than
``max_joint_step`` and the tool stays on the Cartesian segment between the two waypoints
(checked by FK of interpolated configurations, only for the edges that would be chosen and
that a curvature bound does not already prove on the segment), and is
weighted by its joint travel (plus the distance of the start from the seed). Dynamic
programming over the ladder (a beam of the ``tracks`` cheapest candidates per waypoint) gives
the cheapest paths; the best few, from distinct starts, are returned. When no candidate of a
waypoint can be reached, the longest feasible prefix is returned with its ``fraction``, as MoveIt's
``computeCartesianPath`` does.

The whole ladder (tracks switching, merging, refilled by new starts) joins every
``ladder``-th waypoint (:class:`PathSettings`) to the one before; between two of them every
track continues itself, and those waypoints are solved in one batch (:func:`_chunk`): the
tracks' steps predicted from their Jacobians, then refined and checked all at once. The
first such batch starts from the starts themselves. A batch that would leave fewer than two
tracks at a waypoint (none, when it began with one) is dropped, and those waypoints go on one
at a time. The paths' errors come from the tip poses computed when their configurations were
refined.
"""

from dataclasses import dataclass, field
import time
from typing import List, Optional, Sequence, Tuple

import numpy as np

from sik_ros.chain import SerialChain
from sik_ros.collision import Obstacle
from sik_ros.rotations import rotation_angle, rotation_log
from sik_ros.solver import pipeline  # noqa: I100 (a sibling module, not the package)
from sik_ros.solver.config import PATH_DEFAULTS
from sik_ros.solver.context import Context, Goal, POSITION
from sik_ros.solver.explore import nearest_turns
from sik_ros.solver.ranking import distinct_mask
from sik_ros.solver.refine import dls_step, Evaluation, follow

#: Interpolation points checked on every edge (fractions of the edge).
EDGE_CHECKS = (0.25, 0.5, 0.75)

#: Most refinement steps of a track onto its next waypoint (a few suffice from a step away).
TRACK_ITERATIONS = 10

#: Table postures nearest the seed among which a position path's starts are chosen.
NEAR_POOL = 48

#: Most refinement steps of a position path's starts onto the first waypoint. Followed from the
#: current state, 137 of 150 Panda seeds reached it, in 8 steps (median), 15 (p90), 27 (most);
#: the others ran to the solver's 40 (measured with steps of at most 0.4 rad; now 0.6). With
#: 25: 0.96-0.97x the time on 2 x 150 position paths, the same paths (success, travel, start).
START_ITERATIONS = 25

#: The beam of pose paths (see :class:`PathSettings`). Measured (paired, Panda): 12 starts
#: instead of 16 with 12 tracks, 0.95-0.97x the time on 240 paths; then 10 and 10, another
#: 0.93-0.96x on 440 paths, with the same success and travel within 2 %; 8 and 8 were faster
#: still but made the short pose paths longer than the seeded TRAC-IK's. A ladder waypoint every
#: 64 instead of 16 made them 4 % longer (``docs/benchmarks.md``).
POSE_BEAM = {'starts': 10, 'tracks': 10, 'ladder': 16}

#: The beam of position paths. A position waypoint leaves a redundant arm ``n - 3`` dimensions
#: of self-motion, so a track is seldom lost and a narrow beam keeps the paths as short.
#: Measured (paired, Panda, 100 position paths each): 4 starts and 4 tracks instead of 10 and
#: 10, 0.71x the time; then a ladder waypoint every 64 instead of 16, 0.77x; the same success
#: and travel. The first batch from the starts themselves: 0.92x. Batches cut at 10 cm of path
#: (their predicted steps drift from the path as about the cube of its length) were tried:
#: 0.96x in one run, 1.13x in another (300 paths), so left out.
POSITION_BEAM = {'starts': 4, 'tracks': 4, 'ladder': 64}


@dataclass
class JointPath:
    """One joint path through every waypoint (or through the feasible prefix).

    Attributes:
        q: joint positions (N, n) [rad], within the limits.
        position_errors: (N,) [m]; orientation_errors: (N,) [rad].
        max_step: largest joint change between consecutive waypoints [rad].
        travel: total joint travel, the sum of the steps' L2 norms [rad].
        min_obstacle_distance: smallest clearance along the path [m] (+inf without obstacles).
        cost: the ranking cost (travel plus the start's distance from the seed).
    """

    q: np.ndarray
    position_errors: np.ndarray
    orientation_errors: np.ndarray
    max_step: float
    travel: float
    min_obstacle_distance: float
    cost: float


@dataclass
class PathResult:
    """The answer to a path request: ranked joint paths, best first."""

    success: bool
    fraction: float
    paths: List[JointPath] = field(default_factory=list)
    elapsed: float = 0.0
    timed_out: bool = False
    message: str = ''


@dataclass(frozen=True)
class PathSettings:
    """How a path is planned (see :meth:`SelectiveIK.solve_path`).

    ``starts``: distinct solutions asked for at the first waypoint (and where every track is
    lost); ``tracks``: the beam, the cheapest candidates kept per waypoint (both raised to
    ``num_paths`` when below it); ``ladder``: every ``ladder``-th waypoint is joined to the
    previous one by the whole ladder (tracks may switch, merge, be refilled by new starts); the
    waypoints between are solved in one batch, each track continuing itself (:func:`_chunk`).
    ``near_seed``: a position path with a seed starts from the seed and the table's postures
    nearest it (else from the seed and the solver's first solutions, spread over the
    postures: :func:`_starts`). The defaults are :data:`POSE_BEAM`'s; :meth:`for_paths`
    takes them from :data:`POSE_BEAM` or :data:`POSITION_BEAM` by the paths' kind.
    """

    num_paths: int = PATH_DEFAULTS.num_paths
    max_joint_step: float = PATH_DEFAULTS.max_joint_step
    path_tolerance: float = PATH_DEFAULTS.path_tolerance
    orientation_path_tolerance: float = 0.05
    starts: int = POSE_BEAM['starts']
    tracks: int = POSE_BEAM['tracks']
    ladder: int = POSE_BEAM['ladder']
    seed_weight: float = 1.0
    near_seed: bool = True

    def __post_init__(self):
        """Starts and tracks enough for ``num_paths`` paths from distinct starts."""
        object.__setattr__(self, 'starts', max(self.starts, self.num_paths))
        object.__setattr__(self, 'tracks', max(self.tracks, self.num_paths))

    @classmethod
    def for_paths(cls, pose: bool, **kw) -> 'PathSettings':
        """The settings of pose paths (``pose``) or position paths, the beam by their kind."""
        return cls(**{**(POSE_BEAM if pose else POSITION_BEAM), **kw})


def _starts(ctx: Context, goal: Goal, q_seed, obstacles, count: int, deadline,
            near_seed: bool = True) -> Tuple[np.ndarray, Evaluation]:
    """Distinct exact configurations at a waypoint, free of collisions, and their evaluations.

    A path should start near the current state (the seed). At a pose waypoint with a seed the
    solver refines every candidate to its end (the seed's own row among them) for the
    solutions nearest the seed. At a position waypoint with a seed the seed itself and the
    table's postures nearest it (:func:`_near_seed`) are followed onto the waypoint together
    (:func:`_followed`): no decoding or ranking, the rows already near the goal and the
    seed. Without ``near_seed`` (or postures in the table, or with ``cached_postures`` off),
    for starts spread over the postures (a wider beam's second try), the seed followed and
    the solver's first distinct exact solutions. Without a seed (new starts where every track
    was lost) the solver's first distinct exact solutions, as for any goal.

    Measured (paired, against the solver's first distinct exact solutions and the seed
    followed alone): 300 Panda position paths, 0.69x the time, the same success, travel
    0.809 against 0.853 rad and starts 2.28 against 2.55 rad from the current state
    (medians); 150 paths each on the UR5, xArm7 and Kinova, 0.56x, 0.62x and 0.64x the time,
    the same success and start distance, travel +1 %, +1 % and +5 %. Then the table
    postures' periodic joints turned nearest the seed and their last joint set to the seed's
    (a review found both): 0.95x on the Panda, starting 2.14 against 2.28 rad away (Kinova
    2.37 against 2.52), travel within 2 %. Before that, the solver's first solutions without
    the seed followed on its own started Panda paths 3.2 rad from the current state instead
    of 2.0 (median of 88 paths); pose paths took 1.14x the time with the first solutions
    instead of all.
    """
    if goal.rotation is not None or q_seed is None:
        return _solver_starts(ctx, goal, q_seed, obstacles, count, deadline, False)
    near = _near_seed(ctx, goal, q_seed, count) if near_seed else None
    rows = q_seed[None] if near is None else np.concatenate([q_seed[None], near])
    parts = [_followed(ctx, rows, goal, obstacles, deadline)]
    if near is None:
        parts.append(_solver_starts(ctx, goal, q_seed, obstacles, count, deadline, True))
    q, ev = _distinct_union(ctx, *parts)
    if len(q) < min(2, count) and not pipeline.past(deadline):
        # few of them reached the waypoint free of collisions: all the solver's then, as at a
        # pose waypoint
        q, ev = _distinct_union(ctx, (q, ev), _solver_starts(ctx, goal, q_seed, obstacles,
                                                             count, deadline, False))
    return q, ev


def _near_seed(ctx: Context, goal: Goal, q_seed: np.ndarray, count: int
               ) -> Optional[np.ndarray]:
    """Up to ``count - 1`` of the table's postures near a position goal, nearest the seed.

    The postures decoded at the cells nearest the goal (the table's cached ones) are a few
    refinement steps from it. Periodic joints take the 2 pi turn nearest the seed, and a last
    joint that only turns the tool about its axis (:meth:`Context.ignores_last`) the seed's
    own value (refinement leaves it where it is). Of the :data:`NEAR_POOL` nearest the seed
    (L2 over the joints), greedily those distinct from the seed and from each other. None
    when the table keeps no postures or ``config.cached_postures`` is off.
    """
    table = ctx.models[POSITION].table
    if table.postures is None or not ctx.config.cached_postures:
        return None
    rows = table.rows_near(goal.position, ctx.config.k_cells)
    q = np.clip(table.postures[rows].astype(np.float64), ctx.robot.lower, ctx.robot.upper)
    q = nearest_turns(ctx, q, q_seed)
    if ctx.ignores_last(POSITION):
        q[:, -1] = q_seed[-1]
    q = q[np.argsort(np.linalg.norm(q - q_seed, axis=1), kind='stable')[:NEAR_POOL]]
    q = np.concatenate([q_seed[None], q])
    keep = distinct_mask(q, ctx.config.distinct_threshold, ctx.ignores_last(POSITION))
    return q[1:][keep[1:]][:count - 1]


def _followed(ctx: Context, q: np.ndarray, goal: Goal, obstacles,
              deadline) -> Tuple[np.ndarray, Evaluation]:
    """The rows of ``q`` that :func:`follow` takes onto ``goal`` free of collisions.

    They start tracks: no change of their Jacobian from a previous waypoint (the one from the
    current state or a table posture is no waypoint step).
    """
    _, q, ev = follow(ctx, q, Evaluation.of(ctx, q), goal,
                      min(START_ITERATIONS, ctx.config.refine_iterations), deadline)
    free = ~ctx.checker.self_collision(q)
    if obstacles and free.any():
        free[free] = ctx.checker.clearance(q[free], obstacles, deadline) > 0
    ev = ev.rows(free)
    return q[free], Evaluation(ev.p, ev.r, ev.jac, np.zeros_like(ev.jac))


def _distinct_union(ctx: Context, *parts: Tuple[np.ndarray, Evaluation]
                    ) -> Tuple[np.ndarray, Evaluation]:
    """The rows of several position-waypoint starts, in order, one per distinct posture."""
    q = np.concatenate([part[0] for part in parts])
    ev = Evaluation.concat(*(part[1] for part in parts))
    keep = distinct_mask(q, ctx.config.distinct_threshold, ctx.ignores_last(POSITION))
    return q[keep], ev.rows(keep)


def _solver_starts(ctx: Context, goal: Goal, q_seed, obstacles, count: int, deadline,
                   first_found: bool) -> Tuple[np.ndarray, Evaluation]:
    """The solver's exact solutions free of collisions at a waypoint, and their evaluations."""
    res = pipeline.solve(ctx, goal, count, q_seed, obstacles, True, None, deadline,
                         first_found=first_found)
    q = np.array([s.q for s in res.solutions if s.converged and not s.in_collision])
    q = q.reshape(-1, ctx.robot.dof)
    return q, Evaluation.of(ctx, q)


def _continue(ctx: Context, q: np.ndarray, ev: Evaluation, goal: Goal,
              deadline) -> Tuple[np.ndarray, Evaluation]:
    """Each configuration refined onto the next waypoint: the exact ones and their evaluation.

    ``ev`` is the evaluation of ``q`` carried from the previous waypoint (not computed
    again). A track not exact after :data:`TRACK_ITERATIONS` steps is lost (a joint
    limit or a singularity in the way); the others and new starts go on.
    """
    _, q, ev = follow(ctx, q, ev, goal, TRACK_ITERATIONS, deadline)
    return q, ev


def _on_segment(ctx: Context, qa: np.ndarray, qb: np.ndarray, ga: Goal, gb: Goal,
                s: PathSettings) -> np.ndarray:
    """(K,) bool: whether the tool stays on segment ``ga`` -> ``gb`` from ``qa[k]`` to ``qb[k]``.

    Checked by FK at :data:`EDGE_CHECKS` along the joint-space edge: the tool within
    ``path_tolerance`` of the segment and, for pose waypoints, its orientation within
    ``orientation_path_tolerance`` of the turn between the two waypoints' orientations.
    """
    pa, pb = ga.position, gb.position
    seg = pb - pa
    length2 = max(float(seg @ seg), 1e-18)
    t = np.repeat(np.asarray(EDGE_CHECKS), len(qa))
    q = (1 - t)[:, None] * np.tile(qa, (len(EDGE_CHECKS), 1)) + \
        t[:, None] * np.tile(qb, (len(EDGE_CHECKS), 1))
    # a few configurations: one Pinocchio call each beats the vectorised FK's set-up
    p, r = ctx.robot.tip_poses(q, ctx.data)
    u = np.clip(((p - pa) @ seg) / length2, 0.0, 1.0)
    ok = np.linalg.norm(p - (pa + u[:, None] * seg), axis=1) <= s.path_tolerance
    if gb.rotation is not None:
        turn = rotation_angle(ga.rotation, gb.rotation[None])[0]
        near = np.minimum(rotation_angle(ga.rotation, r), rotation_angle(gb.rotation, r))
        ok &= near <= s.orientation_path_tolerance + turn
    return ok.reshape(len(EDGE_CHECKS), len(qa)).all(axis=0)


def _reach(chain: SerialChain) -> np.ndarray:
    """(n, n) ``D[i, j]``: a bound on the tip's distance from the axis of joint ``max(i, j)``.

    The distance from joint k's origin to the tip is at most the sum of the link lengths after
    it, in every configuration; ``d^2 p / dq_i dq_j`` is a double cross product with the
    later joint's lever, so its norm is at most that joint's bound.
    """
    links = np.append(np.linalg.norm(chain.joint_translations[1:], axis=1),
                      np.linalg.norm(chain.tip_translation))
    d = np.cumsum(links[::-1])[::-1]
    k = np.arange(len(d))
    return d[np.maximum(k[:, None], k[None, :])]


def turn_bound(v: np.ndarray, w_a: np.ndarray, w_b: np.ndarray) -> np.ndarray:
    """(K,) a bound on how far the tool turns from the nearer end along joint-space edges.

    Along ``q(t) = qa + t dq`` the tool's angular velocity is ``w(t) = sum_i a_i dq_i`` (the
    joint axes ``a_i``); its derivative is ``sum_{j<i} (a_j x a_i) dq_j dq_i``, of norm at most
    ``W = sum_{j<i} |dq_j| |dq_i|``. The angle from the end at ``t = 0`` is at most
    ``|w(0)| t + W t^2 / 2``, the one from the other end alike, so the nearer end is within
    ``max(|w(0)|, |w(1)|) / 2 + W / 8`` everywhere.

    Args:
        v: ``|dq|`` (K, n).
        w_a, w_b: ``|w|`` at the edges' two ends (K,) [rad] (``sum |dq|`` bounds both).
    """
    total = v.sum(axis=1)
    pairs = (total * total - (v * v).sum(axis=1)) / 2
    return np.maximum(w_a, w_b) / 2 + pairs / 8


def _certified(ctx: Context, qa: np.ndarray, qb: np.ndarray, gb: Goal, turn: float,
               reach: np.ndarray, s: PathSettings, w_a: np.ndarray,
               w_b: np.ndarray) -> np.ndarray:
    """(K,) bool: edges proven to keep the tool on the segment, so FK need not check them.

    Both ends are exact (within the solver's tolerances). Along ``q(t) = qa + t dq`` the tip's
    acceleration is at most ``M = sum_ij D_ij |dq_i| |dq_j|`` (:func:`_reach`), so the tip is
    within ``M / 8`` of the chord between the ends, itself within the position tolerance of the
    segment. The tool is within :func:`turn_bound` (``w_a``, ``w_b``: its angular speeds at the
    ends) plus the orientation tolerance of the nearer end's waypoint orientation. Edges that
    meet both bounds meet :func:`_on_segment`'s test at every point, not only at its samples.
    """
    cfg = ctx.config
    v = np.abs(qb - qa)
    bend = np.einsum('ki,ij,kj->k', v, reach, v)
    ok = cfg.position_tolerance + bend / 8 <= s.path_tolerance
    if gb.rotation is not None:
        ok &= turn_bound(v, w_a, w_b) + cfg.orientation_tolerance <= \
            s.orientation_path_tolerance + turn
    return ok


def _angular_speed(jac: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """(K,) the tool's angular speed ``|J_w dq|`` for Jacobians (K, 6, n) moving by ``dq``."""
    return np.linalg.norm(np.einsum('krj,kj->kr', jac[:, 3:], dq), axis=1)


def _edges(ctx: Context, prev: np.ndarray, prev_cost: np.ndarray, prev_ev: Evaluation,
           q: np.ndarray, ev: Evaluation, ga: Goal, gb: Goal, turn: float, reach: np.ndarray,
           s: PathSettings) -> np.ndarray:
    """(P, Q) cost of reaching each candidate ``q`` from each ``prev`` (inf: not allowed).

    Edges with a joint step above ``max_joint_step`` are out. The others are checked on the
    segment ``ga`` -> ``gb`` lazily: only those that would be a candidate's cheapest way in,
    until every candidate's cheapest edge passes (the same choice as checking them all).
    Edges :func:`_certified` by a bound (``reach``: :func:`_reach`; the ends' Jacobians from
    ``prev_ev`` and ``ev``; ``turn``: the angle between the waypoints' orientations) pass
    without FK.
    """
    diff = q[None] - prev[:, None]
    travel = np.sqrt(np.einsum('pqn,pqn->pq', diff, diff))
    step = np.abs(diff).max(axis=2)
    total = np.where(step <= s.max_joint_step, prev_cost[:, None] + travel, np.inf)
    checked = np.zeros(total.shape, dtype=bool)
    cols = np.arange(len(q))
    while True:
        best = np.argmin(total, axis=0)
        pending = np.isfinite(total[best, cols]) & ~checked[best, cols]
        if not pending.any():
            return total
        a, b = best[pending], cols[pending]
        checked[a, b] = True
        if gb.rotation is None:
            w_a = w_b = None
        else:
            dq = diff[a, b]
            w_a, w_b = _angular_speed(prev_ev.jac[a], dq), _angular_speed(ev.jac[b], dq)
        proven = _certified(ctx, prev[a], q[b], gb, turn, reach, s, w_a, w_b)
        if proven.all():
            return total  # no cost changed: the cheapest edges stay those just proven
        a, b = a[~proven], b[~proven]
        fine = _on_segment(ctx, prev[a], q[b], ga, gb, s)
        total[a[~fine], b[~fine]] = np.inf


Poses = Tuple[np.ndarray, np.ndarray]  # tip positions (M, 3) and rotations (M, 3, 3)
Chunk = Tuple[List[np.ndarray], List[np.ndarray], Evaluation, List[Poses]]


def _chunk(ctx: Context, q: np.ndarray, ev: Evaluation, cost0: np.ndarray, ga: Goal,
           goals: Sequence[Goal], turns: np.ndarray, reach: np.ndarray, obstacles,
           s: PathSettings, deadline) -> Optional[Chunk]:
    """The tracks ``q`` (T, n) through the next ``goals`` (m waypoints) at once, each its own.

    Along a path a track's next steps are nearly its last one, so all ``m`` are predicted
    together: step ``k`` solves the waypoints' move on the track's Jacobian extrapolated to
    that step's midpoint (``jac + (k + 1/2) djac``), in one batched solve; every predicted
    configuration is then refined onto its own waypoint (:func:`follow`, all rows in one
    batch: one Pinocchio evaluation per configuration, a second for the few not yet exact).
    The edges (each track to itself, from ``ga`` on) are checked as at a single waypoint:
    joint step, the segment bound or FK, clearance. A track failing at a waypoint is lost from
    there (cost inf).

    Returns:
        per waypoint the configurations (T, n) and costs (T,) (``cost0`` plus the travel), the
        evaluation at the last one and per waypoint the tip poses ((T, 3), (T, 3, 3)); or None
        when a waypoint would keep fewer than two tracks (none, when ``q`` holds one) (the
        caller then goes one waypoint at a time, with new starts if need be).
    """
    cfg, robot = ctx.config, ctx.robot
    t, n = q.shape
    m = len(goals)
    pos = np.array([g.position for g in goals])                               # (m, 3)
    rot = None if goals[0].rotation is None else np.array([g.rotation for g in goals])
    dims = 3 if rot is None else 6
    move = np.empty((m, t, dims))  # each step's target move: from the track, then waypoint-wise
    move[0, :, :3] = pos[0] - ev.p
    move[1:, :, :3] = (pos[1:] - pos[:-1])[:, None]
    if rot is not None:
        move[0, :, 3:] = rotation_log(rot[0] @ ev.r.transpose(0, 2, 1))
        move[1:, :, 3:] = rotation_log(rot[1:] @ rot[:-1].transpose(0, 2, 1))[:, None]
    djac = ev.djac
    fresh = ~djac.any(axis=(1, 2))
    if fresh.any():
        # new tracks (starts) carry no change of their Jacobian yet: it is measured one step
        # ahead, so that their steps too are predicted to second order
        ahead = dls_step(ev.jac[fresh, :dims], move[0, fresh], cfg.damping ** 2, np.eye(dims))
        djac = djac.copy()
        djac[fresh] = robot.jacobian_loop(np.clip(q[fresh] + ahead, robot.lower, robot.upper),
                                          ctx.data)[2] - ev.jac[fresh]
    mid = (np.arange(m) + 0.5)[:, None, None, None]
    jac = (ev.jac[None, :, :dims] + mid * djac[None, :, :dims]).reshape(m * t, dims, n)
    dq = dls_step(jac, move.reshape(m * t, dims), cfg.damping ** 2, np.eye(dims))
    guess = np.clip(q + np.cumsum(dq.reshape(m, t, n), axis=0), robot.lower, robot.upper)
    flat = guess.reshape(m * t, n)
    p, r, j = robot.jacobian_loop(flat, ctx.data)
    target = Goal(np.repeat(pos, t, axis=0), None if rot is None else np.repeat(rot, t, axis=0))
    rows, fq, fev = follow(ctx, flat, Evaluation(p, r, j, np.zeros_like(j)), target,
                           TRACK_ITERATIONS, deadline)
    ok = np.zeros(m * t, dtype=bool)
    ok[rows] = True
    flat[rows], j[rows], p[rows], r[rows] = fq, fev.jac, fev.p, fev.r
    qs = flat.reshape(m, t, n)
    jacs = j.reshape(m, t, 6, n)
    before = np.concatenate([q[None], qs[:-1]])                                # (m, t, n)
    jac_before = np.concatenate([ev.jac[None], jacs[:-1]])
    diff = qs - before
    ok = ok.reshape(m, t) & (np.abs(diff).max(axis=2) <= s.max_joint_step)
    # the edges on the segments: the bound, then FK for the rest (waypoint by waypoint)
    d = diff.reshape(-1, n)
    w_a = w_b = None
    if rot is not None:
        w_a, w_b = _angular_speed(jac_before.reshape(-1, 6, n), d), _angular_speed(j, d)
    proven = _certified(ctx, before.reshape(-1, n), flat, goals[0], np.repeat(turns, t),
                        reach, s, w_a, w_b).reshape(m, t)
    for k in np.flatnonzero((ok & ~proven).any(axis=1)):
        cols = np.flatnonzero(ok[k] & ~proven[k])
        ok[k, cols] = _on_segment(ctx, before[k, cols], qs[k, cols], goals[k - 1] if k else ga,
                                  goals[k], s)
    if obstacles:
        live = np.flatnonzero(ok.reshape(-1))
        clear = np.zeros(m * t, dtype=bool)
        clear[live] = ctx.checker.clearance(flat[live], obstacles, deadline) > 0
        ok &= clear.reshape(m, t)
    ok = np.logical_and.accumulate(ok, axis=0)
    if (ok.sum(axis=1) < min(2, t)).any():
        return None
    costs = cost0 + np.cumsum(np.linalg.norm(diff, axis=2), axis=0)
    costs = np.where(ok, costs, np.inf)
    last = slice((m - 1) * t, m * t)
    out_ev = Evaluation(p[last], r[last], j[last], j[last] - jac_before[-1])
    tips = list(zip(p.reshape(m, t, 3), r.reshape(m, t, 3, 3)))
    return list(qs), list(costs), out_ev, tips


def _turns(goals: Sequence[Goal]) -> np.ndarray:
    """(N - 1,) the angles [rad] between consecutive waypoints' orientations (0: positions)."""
    if len(goals) < 2 or goals[0].rotation is None:
        return np.zeros(max(len(goals) - 1, 0))
    r = np.array([g.rotation for g in goals])
    return rotation_angle(r[:-1], r[1:])


def solve_path(ctx: Context, goals: Sequence[Goal], q_seed: Optional[np.ndarray],
               obstacles: Sequence[Obstacle], s: PathSettings, deadline: Optional[float],
               wider: Optional[PathSettings] = None) -> PathResult:
    """The ranked joint paths through ``goals`` (checked waypoints), see the module's docstring.

    When the path fails within its time and ``wider`` is given (a wider beam), it is planned
    again with it, and the answer that reaches further is returned: a narrow beam of position
    paths seldom loses every track, but when it does, the tracks of a wider one, from starts
    spread over the postures (``wider.near_seed`` False), may be on a branch that gets
    through (measured: 6 of 600 Panda position paths, 1 when the narrow beam too started
    from the solver's solutions; each solved again).
    """
    result = _plan(ctx, goals, q_seed, obstacles, s, deadline)
    if result.success or result.timed_out or wider is None:
        return result
    again = _plan(ctx, goals, q_seed, obstacles, wider, deadline)
    best = again if again.fraction > result.fraction else result
    best.elapsed = result.elapsed + again.elapsed
    return best


def _plan(ctx: Context, goals: Sequence[Goal], q_seed: Optional[np.ndarray],
          obstacles: Sequence[Obstacle], s: PathSettings,
          deadline: Optional[float]) -> PathResult:
    """One planning of the ranked joint paths with the settings ``s``."""
    t0 = time.perf_counter()
    n = len(goals)
    cand: List[np.ndarray] = []          # candidates per waypoint (M_i, dof)
    back: List[np.ndarray] = []          # best predecessor per candidate (-1: a start)
    cost: List[np.ndarray] = []          # best cost to reach each candidate
    tips: List[Poses] = []               # their tip poses
    reached = 0
    timed_out = False
    reach = _reach(ctx.robot.chain)
    turns = _turns(goals)
    i = one_by_one = 0
    while i < n:
        goal = goals[i]
        if deadline is not None and time.perf_counter() > deadline:
            timed_out = True
            break
        if i == 0:
            q, ev = _starts(ctx, goal, q_seed, obstacles, s.starts, deadline, s.near_seed)
            c0 = np.zeros(len(q)) if q_seed is None else \
                s.seed_weight * np.linalg.norm(q - q_seed, axis=1)
            if len(q) == 0:
                break
            cand.append(q), back.append(np.full(len(q), -1)), cost.append(c0)
            tips.append((ev.p, ev.r))
            reached = i = 1
            continue
        live = np.isfinite(cost[-1])
        prev, prev_idx = cand[-1], np.arange(len(live))
        prev_ev = ev
        if not live.all():
            prev, prev_idx, prev_ev = prev[live], prev_idx[live], ev.rows(live)
        # the waypoints up to the next ladder one (the first run of them from the starts,
        # already distinct: no ladder step before it)
        if ((i - 1) % s.ladder or i == 1) and i >= one_by_one:
            m = min(s.ladder - (i - 1) % s.ladder, n - i)
            out = _chunk(ctx, prev, prev_ev, cost[-1][prev_idx], goals[i - 1],
                         goals[i:i + m], turns[i - 1:i - 1 + m], reach, obstacles, s, deadline)
            if out is None:
                one_by_one = i + m  # no second try before the next ladder waypoint
            else:
                for k, (qk, ck) in enumerate(zip(*out[:2])):
                    cand.append(qk), cost.append(ck), tips.append(out[3][k])
                    back.append(prev_idx if k == 0 else np.arange(len(qk)))
                ev = out[2]
                reached = i = i + m
                continue
        q, ev = _continue(ctx, prev, prev_ev, goal, deadline)
        if len(q) < 2:  # tracks lost: new starts here, joined by the edges that allow it
            fresh, fresh_ev = _starts(ctx, goal, None, obstacles, s.starts, deadline)
            q = np.concatenate([q, fresh])
            ev = Evaluation.concat(ev, fresh_ev)
        if len(q) == 0:
            break
        unique = distinct_mask(q, 1e-3)
        q, ev = q[unique], ev.rows(unique)
        if obstacles:
            clear = ctx.checker.clearance(q, obstacles, deadline) > 0
            q, ev = q[clear], ev.rows(clear)
            if len(q) == 0:
                break
        total = _edges(ctx, prev, cost[-1][prev_idx], prev_ev, q, ev, goals[i - 1], goal,
                       turns[i - 1], reach, s)
        best = np.argmin(total, axis=0)
        c = total[best, np.arange(len(q))]
        if not np.isfinite(c).any():
            break
        keep = np.argsort(c, kind='stable')[:s.tracks]  # a beam: the cheapest tracks go on
        cand.append(q[keep]), back.append(prev_idx[best][keep]), cost.append(c[keep])
        ev = ev.rows(keep)
        tips.append((ev.p, ev.r))
        reached = i = i + 1
    # a step that ran past the deadline (a solve, a clearance check) may have cut it short
    timed_out = timed_out or (reached < n and pipeline.past(deadline))
    paths = _paths(ctx, goals, cand, back, cost, tips, obstacles, s)
    success = reached == n and bool(paths)
    fraction = reached / n if paths else 0.0
    msg = '' if success else (
        f'the path is feasible up to waypoint {reached} of {n}' if paths else
        'no exact, collision-free configuration at the first waypoint')
    if timed_out:
        msg = f'timed out: {msg}'
    return PathResult(success, fraction, paths, time.perf_counter() - t0, timed_out, msg)


def _paths(ctx: Context, goals, cand, back, cost, tips, obstacles,
           s: PathSettings) -> List[JointPath]:
    """The best paths to the last reached waypoint, from distinct starts, best first.

    Their errors come from the candidates' tip poses (``tips``, each waypoint's, computed by
    Pinocchio when the candidates were refined), not from FK again.
    """
    if not cand:
        return []
    ends = np.argsort(cost[-1], kind='stable')
    ends = ends[np.isfinite(cost[-1][ends])]
    m = len(cand)
    # every end's rows at once, waypoint by waypoint back to the start
    rows = np.empty((m, len(ends)), dtype=int)
    rows[-1] = ends
    for i in range(m - 1, 0, -1):
        rows[i - 1] = back[i][rows[i]]
    qs = np.stack([cand[i][rows[i]] for i in range(m)], axis=1)          # (E, m, n)
    ps = np.stack([tips[i][0][rows[i]] for i in range(m)], axis=1)       # (E, m, 3)
    positions = np.array([g.position for g in goals[:m]])
    rotations = None if goals[0].rotation is None else np.array([g.rotation for g in goals[:m]])
    out, starts = [], []
    for k, e in enumerate(ends):
        if len(out) >= s.num_paths:
            break
        q = qs[k]
        if any(np.abs(q[0] - other).max() < 1e-6 for other in starts):
            continue  # the same start as a better path: not a distinct alternative
        starts.append(q[0])
        perr = np.linalg.norm(ps[k] - positions, axis=1)
        if rotations is None:
            oerr = np.zeros(m)
        else:
            r = np.array([tips[i][1][rows[i, k]] for i in range(m)])
            oerr = rotation_angle(rotations, r)
        steps = np.diff(q, axis=0)
        clear = ctx.checker.clearance(q, obstacles) if obstacles else np.full(m, np.inf)
        out.append(JointPath(q, perr, oerr, float(np.abs(steps).max()) if len(steps) else 0.0,
                             float(np.linalg.norm(steps, axis=1).sum()),
                             float(clear.min()), float(cost[-1][e])))
    return out
