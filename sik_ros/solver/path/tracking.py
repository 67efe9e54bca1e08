"""Batches of waypoints between ladder waypoints, each track continuing itself."""

from typing import List, Optional, Sequence, Tuple

import numpy as np

from sik_ros.rotations import rotation_angle, rotation_log
from sik_ros.solver.context import Context, Goal
from sik_ros.solver.path.edges import angular_speed, certified, on_segment
from sik_ros.solver.path.settings import PathSettings, TRACK_ITERATIONS
from sik_ros.solver.refine import dls_step, Evaluation, follow


Poses = Tuple[np.ndarray, np.ndarray]  # tip positions (M, 3) and rotations (M, 3, 3)
Chunk = Tuple[List[np.ndarray], List[np.ndarray], Evaluation, List[Poses]]


def chunk(ctx: Context, q: np.ndarray, ev: Evaluation, cost0: np.ndarray, ga: Goal,
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
        w_a, w_b = angular_speed(jac_before.reshape(-1, 6, n), d), angular_speed(j, d)
    proven = certified(ctx, before.reshape(-1, n), flat, goals[0], np.repeat(turns, t),
                       reach, s, w_a, w_b).reshape(m, t)
    for k in np.flatnonzero((ok & ~proven).any(axis=1)):
        cols = np.flatnonzero(ok[k] & ~proven[k])
        ok[k, cols] = on_segment(ctx, before[k, cols], qs[k, cols], goals[k - 1] if k else ga,
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


def waypoint_turns(goals: Sequence[Goal]) -> np.ndarray:
    """(N - 1,) the angles [rad] between consecutive waypoints' orientations (0: positions)."""
    if len(goals) < 2 or goals[0].rotation is None:
        return np.zeros(max(len(goals) - 1, 0))
    r = np.array([g.rotation for g in goals])
    return rotation_angle(r[:-1], r[1:])
