"""The ladder: dynamic programming over the waypoints' candidates, and the ranked paths."""

import time
from typing import List, Optional, Sequence

import numpy as np

from sik_ros.collision import Obstacle
from sik_ros.deadline import Deadline
from sik_ros.rotations import rotation_angle
from sik_ros.solver.context import Context, Goal
from sik_ros.solver.path.edges import continue_tracks, edge_costs, reach_bounds
from sik_ros.solver.path.settings import JointPath, PathResult, PathSettings
from sik_ros.solver.path.starts import track_starts
from sik_ros.solver.path.tracking import chunk, Poses, waypoint_turns
from sik_ros.solver.ranking import distinct_mask
from sik_ros.solver.refine import Evaluation


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
    cand: List[np.ndarray] = []          # candidates per waypoint (M_i, dof)
    back: List[np.ndarray] = []          # best predecessor per candidate (-1: a start)
    cost: List[np.ndarray] = []          # best cost to reach each candidate
    tips: List[Poses] = []               # their tip poses
    reached = 0
    timed_out = False
    reach = reach_bounds(ctx.robot.chain)
    turns = waypoint_turns(goals)
    i = one_by_one = 0
    while i < n:
        goal = goals[i]
        if deadline.expired():
            timed_out = True
            break
        if i == 0:
            q, ev = track_starts(ctx, goal, q_seed, obstacles, s.starts, deadline, s.near_seed)
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
            out = chunk(ctx, prev, prev_ev, cost[-1][prev_idx], goals[i - 1],
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
        q, ev = continue_tracks(ctx, prev, prev_ev, goal, deadline)
        if len(q) < 2:  # tracks lost: new starts here, joined by the edges that allow it
            fresh, fresh_ev = track_starts(ctx, goal, None, obstacles, s.starts, deadline)
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
        total = edge_costs(ctx, prev, cost[-1][prev_idx], prev_ev, q, ev, goals[i - 1], goal,
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
    timed_out = timed_out or (reached < n and deadline.expired())
    paths = ranked_paths(ctx, goals, cand, back, cost, tips, obstacles, s)
    success = reached == n and bool(paths)
    fraction = reached / n if paths else 0.0
    msg = '' if success else (
        f'the path is feasible up to waypoint {reached} of {n}' if paths else
        'no exact, collision-free configuration at the first waypoint')
    if timed_out:
        msg = f'timed out: {msg}'
    return PathResult(success, fraction, paths, time.perf_counter() - t0, timed_out, msg)


def ranked_paths(ctx: Context, goals, cand, back, cost, tips, obstacles,
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
