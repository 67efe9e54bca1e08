"""Algorithm 2 of the paper: adjust posture indices with an evaluation function.

:func:`adjust_index`: while the clearance from obstacles improves (refined solutions).
:func:`adjust_raw`: while the decoded tip pose comes closer to a pose goal (raw answers: the
answers stay the decoder's outputs, at adjusted indices).
"""

from typing import List, Optional, Sequence

import numpy as np

from sik_ros.deadline import Deadline, NO_DEADLINE
from sik_ros.kinematics.collision import Obstacle
from sik_ros.kinematics.rotations import rotation_log
from sik_ros.solver.batch import Candidates
from sik_ros.solver.codec import decode
from sik_ros.solver.config import (ADJUST_STARTS, ADJUST_STEP, RAW_DAMPING, RAW_DIFFERENCE,
                                   RAW_ORIENTATION_WEIGHT, RAW_ROUNDS)
from sik_ros.solver.context import Context, Goal
from sik_ros.solver.refine import errors, refine
from sik_ros.solver.results import Solution
from sik_ros.solver.scores import converged, distinct_mask, pose_score


def adjust_index(ctx: Context, goal: Goal, sols: Sequence[Solution],
                 obstacles: Sequence[Obstacle], deadline: Deadline = NO_DEADLINE,
                 step: float = ADJUST_STEP) -> Optional[List[Solution]]:
    """Move posture indices element by element while the clearance improves.

    Starts from the best colliding solutions; each trial decodes and refines the neighbours of
    an index (one element moved by ``step`` times its range in the table, either way); it
    stops at a collision-free exact solution or when ``config.adjust_budget`` decodes are
    spent.

    Returns:
        the improving solutions found, last best, or None.
    """
    cfg = ctx.config
    starts = [s for s in sols if s.converged][:ADJUST_STARTS] or list(sols[:ADJUST_STARTS])
    budget = cfg.adjust_budget
    found: List[Solution] = []
    lo, hi = ctx.models[goal.kind].table.index_bounds
    for s in starts:
        z = s.posture_index.astype(np.float64)
        best = s.min_obstacle_distance
        while budget > 0 and not deadline.expired():
            trials = []
            for d in range(len(z)):
                for sign in (1.0, -1.0):
                    t = z.copy()
                    t[d] = np.clip(t[d] + sign * step * (hi[d] - lo[d]), lo[d], hi[d])
                    trials.append(t)
            trials = np.array(trials)
            budget -= len(trials)
            r = refine(ctx, decode(ctx, goal, trials), goal, deadline)
            exact = converged(r.perr, r.oerr, goal.kind, cfg)
            clear = ctx.checker.clearance(r.q, obstacles, deadline)
            clear = np.where(ctx.checker.self_collision(r.q) | ~exact | np.isnan(clear), -np.inf,
                             clear)
            i = int(np.argmax(clear))
            if clear[i] <= best:
                break
            best, z = clear[i], trials[i]
            found.append(Solution(q=r.q[i], position_error=float(r.perr[i]),
                                  orientation_error=float(r.oerr[i]),
                                  posture_index=trials[i].astype(np.float32),
                                  min_obstacle_distance=float(clear[i]), converged=True))
            if best > 0:
                break
        if found and found[-1].min_obstacle_distance > 0:
            break
    return found or None


def raw_starts(num: int) -> int:
    """Raw candidates whose indices are adjusted first for a call asking for ``num``."""
    return 2 * num + 4


def _pose_residual(ctx: Context, goal: Goal, q: np.ndarray) -> np.ndarray:
    """(M, 6): tip position error [m] and weighted rotation vector of the orientation error."""
    p, r = ctx.robot.tip_poses(q, ctx.data)
    return np.concatenate([p - goal.position, RAW_ORIENTATION_WEIGHT * rotation_log(
        np.swapaxes(goal.rotation, -1, -2)[None] @ r)], axis=1)


def _gauss_newton(ctx: Context, goal: Goal, z: np.ndarray, q: np.ndarray,
                  deadline: Deadline):
    """Damped Gauss-Newton steps on posture indices towards the goal pose.

    ``config.raw_adjust`` steps on indices ``z`` (M, latent) decoded as ``q`` (M, n); a step is
    kept only when the decoded pose comes closer. Returns the new (z, q).
    """
    lo, hi = ctx.models[goal.kind].table.index_bounds
    res = _pose_residual(ctx, goal, q)
    cost = (res * res).sum(axis=1)
    damping = np.full(len(z), RAW_DAMPING)
    eye = np.eye(z.shape[1])
    for _ in range(ctx.config.raw_adjust):
        if deadline.expired():
            break
        moved = (z[:, None, :] + RAW_DIFFERENCE * eye[None]).reshape(-1, z.shape[1])
        jac = (_pose_residual(ctx, goal, decode(ctx, goal, moved)).reshape(
            len(z), z.shape[1], 6) - res[:, None, :]).transpose(0, 2, 1) / RAW_DIFFERENCE
        jt = jac.transpose(0, 2, 1)
        step = np.linalg.solve(jt @ jac + damping[:, None, None] * eye,
                               -(jt @ res[..., None]))[..., 0]
        trial = np.clip(z + step, lo, hi)
        q_trial = decode(ctx, goal, trial)
        res_trial = _pose_residual(ctx, goal, q_trial)
        cost_trial = (res_trial * res_trial).sum(axis=1)
        better = cost_trial < cost
        z[better], q[better] = trial[better], q_trial[better]
        res[better], cost[better] = res_trial[better], cost_trial[better]
        damping = np.where(better, damping / 3, damping * 4)
    return z, q


def adjust_raw(ctx: Context, goal: Goal, c: Candidates, num: int, skip_first: bool = False,
               deadline: Deadline = NO_DEADLINE) -> Candidates:
    """Raw candidates for a pose goal with the best ones' posture indices adjusted.

    Algorithm 2 with the tip pose error as its evaluation function: the best distinct
    candidates (by :func:`~sik_ros.solver.scores.pose_score`) take ``config.raw_adjust``
    damped Gauss-Newton steps on their index, each on the error's finite-difference derivative
    with respect to the index (one decode per index element), kept only when the decoded pose
    comes closer (position error plus ``config.RAW_ORIENTATION_WEIGHT`` per radian). When the
    adjusted ones come together on fewer distinct postures than ``num``, the next best are
    adjusted (at most ``config.RAW_ROUNDS`` rounds). With ``skip_first`` the first row (the
    seed's own index, whose posture a seeded raw answer keeps) is left as it is. The answers
    stay decoded postures (no joint-space refinement): the pose model's table holds indices of
    rows of other orientations, and its decoder reaches the goal orientation only near the
    index of a posture that has it (docs/training.md).

    Returns:
        ``c`` with the adjusted rows replaced in place (same order and length).
    """
    if ctx.config.raw_adjust <= 0 or len(c) == 0 or goal.rotation is None:
        return c
    cfg = ctx.config
    out = Candidates(c.q.copy(), c.z.astype(np.float64), c.perr.copy(), c.oerr.copy(),
                     c.exact.copy())
    done = np.zeros(len(c), dtype=bool)
    done[0] = skip_first
    want = raw_starts(num)
    for _ in range(RAW_ROUNDS):
        rest = np.flatnonzero(~done)
        if not len(rest) or deadline.expired():
            break
        rest = rest[np.argsort(pose_score(c.perr[rest], c.oerr[rest]), kind='stable')]
        rows = rest[distinct_mask(c.q[rest], cfg.distinct_threshold)][:want]
        z, q = _gauss_newton(ctx, goal, out.z[rows], out.q[rows], deadline)
        perr, oerr = errors(ctx, q, goal)
        out.q[rows], out.z[rows], out.perr[rows], out.oerr[rows] = q, z, perr, oerr
        out.exact[rows] = converged(perr, oerr, goal.kind, cfg)
        done[rows] = True
        adjusted = np.flatnonzero(done)
        adjusted = adjusted[np.argsort(pose_score(out.perr[adjusted], out.oerr[adjusted]),
                                       kind='stable')]
        adjusted = adjusted[distinct_mask(out.q[adjusted], cfg.distinct_threshold)]
        # the ranking puts postures that collide with the arm itself last: count free ones
        have = int((~ctx.checker.self_collision(out.q[adjusted])).sum())
        if have >= num:
            break
        want = 2 * (num - have) + 2
    return out
