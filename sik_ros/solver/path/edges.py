"""Edges of the ladder: continuing tracks onto the next waypoint, and checking each step."""

from typing import Tuple

import numpy as np

from sik_ros.deadline import Deadline
from sik_ros.kinematics.chain import SerialChain
from sik_ros.kinematics.rotations import rotation_angle
from sik_ros.solver.config import EDGE_CHECKS, TRACK_ITERATIONS
from sik_ros.solver.context import Context, Goal
from sik_ros.solver.path.settings import PathSettings
from sik_ros.solver.refine import Evaluation, follow


def continue_tracks(ctx: Context, q: np.ndarray, ev: Evaluation, goal: Goal,
                    deadline: Deadline) -> Tuple[np.ndarray, Evaluation]:
    """Each configuration refined onto the next waypoint: the exact ones and their evaluation.

    ``ev`` is the evaluation of ``q`` carried from the previous waypoint (not computed
    again). A track not exact after :data:`TRACK_ITERATIONS` steps is lost (a joint
    limit or a singularity in the way); the others and new starts go on.
    """
    _, q, ev = follow(ctx, q, ev, goal, TRACK_ITERATIONS, deadline)
    return q, ev


def on_segment(ctx: Context, qa: np.ndarray, qb: np.ndarray, ga: Goal, gb: Goal,
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


def reach_bounds(chain: SerialChain) -> np.ndarray:
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


def certified(ctx: Context, qa: np.ndarray, qb: np.ndarray, gb: Goal, turn: float,
              reach: np.ndarray, s: PathSettings, w_a: np.ndarray,
              w_b: np.ndarray) -> np.ndarray:
    """(K,) bool: edges proven to keep the tool on the segment, so FK need not check them.

    Both ends are exact (within the solver's tolerances). Along ``q(t) = qa + t dq`` the tip's
    acceleration is at most ``M = sum_ij D_ij |dq_i| |dq_j|`` (:func:`reach_bounds`), so the tip is
    within ``M / 8`` of the chord between the ends, itself within the position tolerance of the
    segment. The tool is within :func:`turn_bound` (``w_a``, ``w_b``: its angular speeds at the
    ends) plus the orientation tolerance of the nearer end's waypoint orientation. Edges that
    meet both bounds meet :func:`on_segment`'s test at every point, not only at its samples.
    """
    cfg = ctx.config
    v = np.abs(qb - qa)
    bend = np.einsum('ki,ij,kj->k', v, reach, v)
    ok = cfg.position_tolerance + bend / 8 <= s.path_tolerance
    if gb.rotation is not None:
        ok &= turn_bound(v, w_a, w_b) + cfg.orientation_tolerance <= \
            s.orientation_path_tolerance + turn
    return ok


def angular_speed(jac: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """(K,) the tool's angular speed ``|J_w dq|`` for Jacobians (K, 6, n) moving by ``dq``."""
    return np.linalg.norm(np.einsum('krj,kj->kr', jac[:, 3:], dq), axis=1)


def edge_costs(ctx: Context, prev: np.ndarray, prev_cost: np.ndarray, prev_ev: Evaluation,
               q: np.ndarray, ev: Evaluation, ga: Goal, gb: Goal, turn: float, reach: np.ndarray,
               s: PathSettings) -> np.ndarray:
    """(P, Q) cost of reaching each candidate ``q`` from each ``prev`` (inf: not allowed).

    Edges with a joint step above ``max_joint_step`` are out. The others are checked on the
    segment ``ga`` -> ``gb`` lazily: only those that would be a candidate's cheapest way in,
    until every candidate's cheapest edge passes (the same choice as checking them all).
    Edges :func:`certified` by a bound (``reach``: :func:`reach_bounds`; the ends' Jacobians from
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
            w_a, w_b = angular_speed(prev_ev.jac[a], dq), angular_speed(ev.jac[b], dq)
        proven = certified(ctx, prev[a], q[b], gb, turn, reach, s, w_a, w_b)
        if proven.all():
            return total  # no cost changed: the cheapest edges stay those just proven
        a, b = a[~proven], b[~proven]
        fine = on_segment(ctx, prev[a], q[b], ga, gb, s)
        total[a[~fine], b[~fine]] = np.inf
