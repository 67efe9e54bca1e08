"""Batches of waypoints between ladder waypoints, each track continuing itself."""

from typing import List, Optional, Tuple

import numpy as np

from sik_ros.deadline import Deadline
from sik_ros.kernels import as_arg
from sik_ros.kernels.follow import predict_rows
from sik_ros.kinematics.rotations import rotation_log
from sik_ros.solver.config import TRACK_ITERATIONS
from sik_ros.solver.context import Context, Goal
from sik_ros.solver.path.edges import angular_speed, certified, on_segment
from sik_ros.solver.path.rungs import Plan, Rung, Tracks
from sik_ros.solver.refine import Evaluation, follow


def chunk(plan: Plan, tracks: Tracks, i: int, m: int
          ) -> Optional[Tuple[List[Rung], Evaluation]]:
    """The tracks through waypoints ``i`` to ``i + m - 1`` at once, each its own.

    Along a path a track's next steps are nearly its last one, so all ``m`` are predicted
    together (:func:`predicted`); every predicted configuration is then refined onto its own
    waypoint (:func:`follow`, all rows in one batch: one Pinocchio evaluation per
    configuration, a second for the few not yet exact). The edges (each track to itself, from
    waypoint ``i - 1`` on) are checked as at a single waypoint (:func:`edges_ok`). A track
    failing at a waypoint is lost from there (cost inf).

    Returns:
        the ``m`` rungs (costs: the tracks' plus their travel) and the evaluation at the last
        one; or None when a waypoint would keep fewer than two tracks (none, when there is
        one track) (the caller then goes one waypoint at a time, with new starts if need be).
    """
    ctx, q, ev = plan.ctx, tracks.q, tracks.ev
    t, n = q.shape
    goals = plan.goals[i:i + m]
    pos = np.array([g.position for g in goals])                               # (m, 3)
    rot = None if goals[0].rotation is None else np.array([g.rotation for g in goals])
    flat = predicted(ctx, q, ev, pos, rot)
    flat, p, r, j, ok = refined(ctx, flat, pos, rot, t, plan.deadline)
    ok, diff, jac_before = edges_ok(plan, i, tracks, flat, j, ok)
    if (ok.sum(axis=1) < min(2, t)).any():
        return None
    costs = tracks.cost + np.cumsum(np.linalg.norm(diff, axis=2), axis=0)
    costs = np.where(ok, costs, np.inf)
    last = slice((m - 1) * t, m * t)
    out_ev = Evaluation(p[last], r[last], j[last], j[last] - jac_before[-1])
    qs, ps, rs = flat.reshape(m, t, n), p.reshape(m, t, 3), r.reshape(m, t, 3, 3)
    rungs = [Rung(qs[k], tracks.rows if k == 0 else np.arange(t), costs[k], ps[k], rs[k])
             for k in range(m)]
    return rungs, out_ev


def moves(ev: Evaluation, pos: np.ndarray, rot: Optional[np.ndarray]) -> np.ndarray:
    """(m, T, dims) each step's target move: from each track to the first waypoint, then on.

    ``pos`` (m, 3) [m] and ``rot`` (m, 3, 3) (None: positions) are the waypoints; the moves'
    rotations are rotation vectors [rad].
    """
    m, t = len(pos), len(ev.p)
    dims = 3 if rot is None else 6
    move = np.empty((m, t, dims))
    move[0, :, :3] = pos[0] - ev.p
    move[1:, :, :3] = (pos[1:] - pos[:-1])[:, None]
    if rot is not None:
        move[0, :, 3:] = rotation_log(rot[0] @ ev.r.transpose(0, 2, 1))
        move[1:, :, 3:] = rotation_log(rot[1:] @ rot[:-1].transpose(0, 2, 1))[:, None]
    return move


def jacobian_change(ctx: Context, q: np.ndarray, ev: Evaluation,
                    first: np.ndarray) -> np.ndarray:
    """(T, 6, n) each track's change of Jacobian per step: its last one, or measured ahead.

    New tracks (starts) carry no change of their Jacobian yet: it is measured one step
    ahead (towards ``first``, their move to the first waypoint (T, dims)), so that their
    steps too are predicted to second order.
    """
    cfg, robot = ctx.config, ctx.robot
    dims = first.shape[1]
    djac = ev.djac
    fresh = ~djac.any(axis=(1, 2))
    if fresh.any():
        # one damped least squares step (the kernels' one formula), within the limits
        jac = as_arg(ev.jac[fresh])
        ahead = np.empty((1, len(jac), q.shape[1]))
        predict_rows(as_arg(q[fresh]), jac, np.zeros_like(jac), as_arg(first[fresh][None]),
                     dims, cfg.damping ** 2, robot.lower, robot.upper, ahead)
        djac = djac.copy()
        djac[fresh] = robot.jacobian_loop(ahead[0], ctx.data)[2] - jac
    return djac


def predicted(ctx: Context, q: np.ndarray, ev: Evaluation, pos: np.ndarray,
              rot: Optional[np.ndarray]) -> np.ndarray:
    """(m * T, n) the tracks ``q`` (T, n) predicted at each of the waypoints ``pos``, ``rot``.

    Step ``k`` solves the waypoints' move on the track's Jacobian extrapolated to that step's
    midpoint (``jac + (k + 1/2) djac``), the steps summed within the limits
    (:func:`~sik_ros.kernels.dls.predict_rows`, one compiled call).
    """
    cfg, robot = ctx.config, ctx.robot
    (t, n), m = q.shape, len(pos)
    move = moves(ev, pos, rot)
    djac = jacobian_change(ctx, q, ev, move[0])
    guess = np.empty((m, t, n))
    predict_rows(as_arg(q), as_arg(ev.jac), as_arg(djac), move, move.shape[2],
                 cfg.damping ** 2, robot.lower, robot.upper, guess)
    return guess.reshape(m * t, n)


def refined(ctx: Context, flat: np.ndarray, pos: np.ndarray, rot: Optional[np.ndarray],
            t: int, deadline: Deadline) -> Tuple[np.ndarray, ...]:
    """Predicted rows (m * T, n) refined onto their own waypoints, in place.

    Returns:
        the rows, their tip positions, rotations and Jacobians, and whether each is exact.
    """
    p, r, j = ctx.robot.jacobian_loop(flat, ctx.data)
    target = Goal(np.repeat(pos, t, axis=0), None if rot is None else np.repeat(rot, t, axis=0))
    rows, fq, fev = follow(ctx, flat, Evaluation(p, r, j, np.zeros_like(j)), target,
                           TRACK_ITERATIONS, deadline)
    ok = np.zeros(len(flat), dtype=bool)
    ok[rows] = True
    flat[rows], j[rows], p[rows], r[rows] = fq, fev.jac, fev.p, fev.r
    return flat, p, r, j, ok


def edges_ok(plan: Plan, i: int, tracks: Tracks, flat: np.ndarray, j: np.ndarray,
             ok: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(m, T) which tracks are still whole at each waypoint of the batch from ``i`` on.

    Each edge (a track from the waypoint before): exact at both ends, a joint step within
    ``max_joint_step``, on the segment (the bound, then FK for the rest, waypoint by
    waypoint), clear of obstacles; a track is lost from its first failing edge.

    Returns:
        that mask, the steps (m, T, n) [rad] and the Jacobians before each step (m, T, 6, n).
    """
    ctx, s, q = plan.ctx, plan.s, tracks.q
    (t, n), m = q.shape, len(flat) // len(q)
    goals = plan.goals[i:i + m]
    qs = flat.reshape(m, t, n)
    before = np.concatenate([q[None], qs[:-1]])                                # (m, t, n)
    jac_before = np.concatenate([tracks.ev.jac[None], j.reshape(m, t, 6, n)[:-1]])
    diff = qs - before
    ok = ok.reshape(m, t) & (np.abs(diff).max(axis=2) <= s.max_joint_step)
    d = diff.reshape(-1, n)
    w_a = w_b = None
    if goals[0].rotation is not None:
        w_a, w_b = angular_speed(jac_before.reshape(-1, 6, n), d), angular_speed(j, d)
    proven = certified(ctx, before.reshape(-1, n), flat, goals[0],
                       np.repeat(plan.turns[i - 1:i - 1 + m], t), plan.reach, s, w_a,
                       w_b).reshape(m, t)
    for k in np.flatnonzero((ok & ~proven).any(axis=1)):
        cols = np.flatnonzero(ok[k] & ~proven[k])
        ok[k, cols] = on_segment(ctx, before[k, cols], qs[k, cols], plan.goals[i - 1 + k],
                                 goals[k], s)
    if plan.obstacles:
        live = np.flatnonzero(ok.reshape(-1))
        clear = np.zeros(m * t, dtype=bool)
        clear[live] = ctx.checker.clearance(flat[live], plan.obstacles, plan.deadline) > 0
        ok &= clear.reshape(m, t)
    return np.logical_and.accumulate(ok, axis=0), diff, jac_before
