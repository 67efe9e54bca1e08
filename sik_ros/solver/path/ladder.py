"""The ladder: dynamic programming over the waypoints' candidates, and the ranked paths."""

import time
from typing import List, Optional, Sequence, Tuple

import numpy as np

from sik_ros.deadline import Deadline
from sik_ros.kinematics.collision import Obstacle
from sik_ros.kinematics.goal_error import goal_errors
from sik_ros.solver.config import SAME_CANDIDATE, SAME_START
from sik_ros.solver.context import Context, Goal
from sik_ros.solver.path.edges import continue_tracks, edge_costs, reach_bounds
from sik_ros.solver.path.rungs import Plan, Rung, Tracks, waypoint_turns
from sik_ros.solver.path.settings import JointPath, PathResult, PathSettings
from sik_ros.solver.path.starts import track_starts
from sik_ros.solver.path.tracking import chunk
from sik_ros.solver.refine import Evaluation
from sik_ros.solver.scores import distinct_mask

#: A rung and the evaluation of its rows (carried into the next waypoint's steps).
Step = Tuple[Rung, Evaluation]


def solve_path(ctx: Context, goals: Sequence[Goal], q_seed: Optional[np.ndarray],
               obstacles: Sequence[Obstacle], s: PathSettings, deadline: Deadline,
               wider: Optional[PathSettings] = None) -> PathResult:
    """The ranked joint paths through ``goals`` (checked waypoints), see the module's docstring.

    When the path fails within its time and ``wider`` is given (a wider beam), it is planned
    again with it, and the answer that reaches further is returned: a narrow beam of position
    paths seldom loses every track, but when it does, the tracks of a wider one, from starts
    spread over the postures (``wider.near_seed`` False), may be on a branch that gets
    through.
    """
    result = plan(ctx, goals, q_seed, obstacles, s, deadline)
    if result.success or result.timed_out or wider is None:
        return result
    again = plan(ctx, goals, q_seed, obstacles, wider, deadline)
    best = again if again.fraction > result.fraction else result
    best.elapsed = result.elapsed + again.elapsed
    return best


def plan(ctx: Context, goals: Sequence[Goal], q_seed: Optional[np.ndarray],
         obstacles: Sequence[Obstacle], s: PathSettings,
         deadline: Deadline) -> PathResult:
    """One planning of the ranked joint paths with the settings ``s``."""
    t0 = time.perf_counter()
    n = len(goals)
    p = Plan(ctx, goals, obstacles, s, deadline, reach_bounds(ctx.robot.chain),
             waypoint_turns(goals))
    rungs, timed_out = climb(p, q_seed)
    reached = len(rungs)
    # a step that ran past the deadline (a solve, a clearance check) may have cut it short
    timed_out = timed_out or (reached < n and deadline.expired())
    paths = ranked_paths(p, rungs)
    success = reached == n and bool(paths)
    fraction = reached / n if paths else 0.0
    msg = '' if success else (
        f'the path is feasible up to waypoint {reached} of {n}' if paths else
        'no exact, collision-free configuration at the first waypoint')
    if timed_out:
        msg = f'timed out: {msg}'
    return PathResult(success, fraction, paths, time.perf_counter() - t0, timed_out, msg)


def climb(p: Plan, q_seed: Optional[np.ndarray]) -> Tuple[List[Rung], bool]:
    """The rungs of the waypoints reached, in order, and whether the deadline stopped it.

    The first rung holds the starts; the waypoints up to the next ladder one are solved in one
    batch (:func:`chunk`; the first run of them from the starts, already distinct: no ladder
    step before it); a batch that fails leaves its waypoints to :func:`next_rung`, one at a
    time.
    """
    n, every = len(p.goals), p.s.ladder
    rungs: List[Rung] = []
    ev = None  # the evaluation of the last rung's rows
    one_by_one = 0  # no batch before this waypoint (one failed)
    while len(rungs) < n:
        i = len(rungs)
        if p.deadline.expired():
            return rungs, True
        if i == 0:
            step = first_rung(p, q_seed)
        else:
            tracks = Tracks.of(rungs[-1], ev)
            if ((i - 1) % every or i == 1) and i >= one_by_one:
                m = min(every - (i - 1) % every, n - i)
                batch = chunk(p, tracks, i, m)
                if batch is not None:
                    rungs.extend(batch[0])
                    ev = batch[1]
                    continue
                one_by_one = i + m  # no second try before the next ladder waypoint
            step = next_rung(p, tracks, i)
        if step is None:
            break
        rungs.append(step[0])
        ev = step[1]
    return rungs, False


def first_rung(p: Plan, q_seed: Optional[np.ndarray]) -> Optional[Step]:
    """The starts at the first waypoint, each costing its distance from the seed (if any)."""
    s = p.s
    q, ev = track_starts(p.ctx, p.goals[0], q_seed, p.obstacles, s.starts, p.deadline,
                         s.near_seed)
    c0 = np.zeros(len(q)) if q_seed is None else \
        s.seed_weight * np.linalg.norm(q - q_seed, axis=1)
    if len(q) == 0:
        return None
    return Rung(q, np.full(len(q), -1), c0, ev.p, ev.r), ev


def next_rung(p: Plan, tracks: Tracks, i: int) -> Optional[Step]:
    """Waypoint ``i``'s rung: the tracks continued (new starts where they are lost), joined.

    Every candidate takes its cheapest allowed edge from the tracks (:func:`edge_costs`);
    the beam keeps the ``tracks`` cheapest. None when no candidate can be reached.
    """
    ctx, s, deadline, goal = p.ctx, p.s, p.deadline, p.goals[i]
    q, ev = continue_tracks(ctx, tracks.q, tracks.ev, goal, deadline)
    if len(q) < 2:  # tracks lost: new starts here, joined by the edges that allow it
        fresh, fresh_ev = track_starts(ctx, goal, None, p.obstacles, s.starts, deadline)
        q = np.concatenate([q, fresh])
        ev = Evaluation.concat(ev, fresh_ev)
    if len(q) == 0:
        return None
    unique = distinct_mask(q, SAME_CANDIDATE)
    q, ev = q[unique], ev.rows(unique)
    if p.obstacles:
        clear = ctx.checker.clearance(q, p.obstacles, deadline) > 0
        q, ev = q[clear], ev.rows(clear)
        if len(q) == 0:
            return None
    total = edge_costs(ctx, tracks.q, tracks.cost, tracks.ev, q, ev, p.goals[i - 1], goal,
                       p.turns[i - 1], p.reach, s)
    best = np.argmin(total, axis=0)
    c = total[best, np.arange(len(q))]
    if not np.isfinite(c).any():
        return None
    keep = np.argsort(c, kind='stable')[:s.tracks]  # a beam: the cheapest tracks go on
    ev = ev.rows(keep)
    return Rung(q[keep], tracks.rows[best][keep], c[keep], ev.p, ev.r), ev


def ranked_paths(p: Plan, rungs: Sequence[Rung]) -> List[JointPath]:
    """The best paths to the last reached waypoint, from distinct starts, best first.

    Their errors come from the candidates' tip poses (each rung's, computed by Pinocchio when
    the candidates were refined), not from FK again.
    """
    if not rungs:
        return []
    cost = rungs[-1].cost
    ends = np.argsort(cost, kind='stable')
    ends = ends[np.isfinite(cost[ends])]
    m = len(rungs)
    # every end's rows at once, waypoint by waypoint back to the start
    rows = np.empty((m, len(ends)), dtype=int)
    rows[-1] = ends
    for i in range(m - 1, 0, -1):
        rows[i - 1] = rungs[i].back[rows[i]]
    qs = np.stack([rungs[i].q[rows[i]] for i in range(m)], axis=1)       # (E, m, n)
    ps = np.stack([rungs[i].p[rows[i]] for i in range(m)], axis=1)       # (E, m, 3)
    goals = p.goals[:m]
    positions = np.array([g.position for g in goals])
    rotations = None if goals[0].rotation is None else np.array([g.rotation for g in goals])
    out, starts = [], []
    for k, e in enumerate(ends):
        if len(out) >= p.s.num_paths:
            break
        q = qs[k]
        if any(np.abs(q[0] - other).max() < SAME_START for other in starts):
            continue  # the same start as a better path: not a distinct alternative
        starts.append(q[0])
        r = None if rotations is None else np.array([rungs[i].r[rows[i, k]] for i in range(m)])
        perr, oerr = goal_errors(ps[k], r, positions, rotations)
        out.append(joint_path(p, q, perr, oerr, float(cost[e])))
    return out


def joint_path(p: Plan, q: np.ndarray, perr: np.ndarray, oerr: np.ndarray,
               cost: float) -> JointPath:
    """A :class:`JointPath` of configurations ``q`` (N, n) with their errors and cost."""
    steps = np.diff(q, axis=0)
    clear = p.ctx.checker.clearance(q, p.obstacles) if p.obstacles else np.full(len(q), np.inf)
    return JointPath(q, perr, oerr, float(np.abs(steps).max()) if len(steps) else 0.0,
                     float(np.linalg.norm(steps, axis=1).sum()), float(clear.min()), cost)
