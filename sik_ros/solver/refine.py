"""Refinement: batched damped least squares towards a goal, within the joint limits.

Every candidate takes steps ``J^T (J J^T + lambda^2 I)^-1 e`` on the chain's Jacobian at once;
joints at a limit that the descent direction pushes further out leave the step (active set).
Candidates that reach the goal, stall far from it, or head for the same solution as a better one
stop early (see :class:`~sik_ros.solver.config.SolverConfig`).
"""

from dataclasses import dataclass
import time
from typing import Optional, Tuple

import numpy as np

from sik_ros.rotations import rotation_angle, rotation_log
from sik_ros.solver.context import Context, Goal
from sik_ros.solver.ranking import distinct_mask, pose_score


@dataclass(frozen=True)
class Refined:
    """The result of :func:`refine`.

    Attributes:
        q: refined configurations (M, n) [rad].
        perr: their position errors (M,) [m].
        oerr: their orientation errors (M,) [rad] (zeros for position goals).
        cut_short: the deadline stopped refinement before every candidate had finished.
    """

    q: np.ndarray
    perr: np.ndarray
    oerr: np.ndarray
    cut_short: bool = False


@dataclass(frozen=True)
class Evaluation:
    """Tip poses and Jacobians of configurations, to carry into the next :func:`follow`.

    Attributes:
        p: tip positions (M, 3) [m]; r: rotations (M, 3, 3); jac: Jacobians (M, 6, n).
        djac: (M, 6, n) how each row's Jacobian changed from the previous waypoint to this
            one (zeros for new rows; kept as it was for a row that did not move): the next
            step, alike along a path, is taken on the Jacobian extrapolated to its midpoint.
    """

    p: np.ndarray
    r: np.ndarray
    jac: np.ndarray
    djac: np.ndarray

    def rows(self, keep: np.ndarray) -> 'Evaluation':
        """The evaluation of the rows ``keep`` (an index or mask)."""
        return Evaluation(self.p[keep], self.r[keep], self.jac[keep], self.djac[keep])

    @staticmethod
    def of(ctx: Context, q: np.ndarray) -> 'Evaluation':
        """The evaluation of new configurations ``q`` (M, n) (no last step)."""
        p, r, jac = ctx.robot.jacobian_loop(q, ctx.data)
        return Evaluation(p, r, jac, np.zeros_like(jac))

    @staticmethod
    def concat(*parts: 'Evaluation') -> 'Evaluation':
        """The rows of several evaluations, in order."""
        return Evaluation(*(np.concatenate([getattr(e, name) for e in parts])
                            for name in ('p', 'r', 'jac', 'djac')))


def errors(ctx: Context, q: np.ndarray, goal: Goal) -> Tuple[np.ndarray, np.ndarray]:
    """Position errors [m] and orientation errors [rad] (zeros for position goals), (M,)."""
    robot = ctx.robot
    p, r = robot.tip_poses(q, ctx.data)
    perr = np.linalg.norm(p - goal.position, axis=1)
    if goal.rotation is None:
        return perr, np.zeros(len(q))
    return perr, rotation_angle(goal.rotation, r)


def dls_step(j: np.ndarray, err: np.ndarray, lam2: float, eye: np.ndarray) -> np.ndarray:
    """Damped least squares steps J^T (J J^T + lambda^2 I)^-1 e for a batch."""
    jjt = j @ j.transpose(0, 2, 1) + lam2 * eye
    return (j.transpose(0, 2, 1) @ np.linalg.solve(jjt, err[..., None]))[..., 0]


def limited_step(ctx: Context, q: np.ndarray, j: np.ndarray, err: np.ndarray, lam2: float,
                 eye: np.ndarray, turn: bool = False) -> np.ndarray:
    """``q`` (M, n) after one damped least squares step on ``err``, within the joint limits.

    Joints at a limit that the descent direction ``J^T e`` pushes further out leave the step
    (active set); a step is scaled down to ``config.max_step`` on its largest joint. With
    ``turn`` (solving, not following a path, where a joint must not jump) a periodic joint (a
    range of a whole turn or more) stepping past a limit is turned back by 2 pi instead: the
    same placement, where a clamp would hold it against the limit.
    """
    robot = ctx.robot
    lower, upper = robot.lower, robot.upper
    turns = turn and robot.periodic.any()
    # with ``turn`` a periodic joint is never held at a limit: it comes back in by a turn
    bounded = ~robot.periodic if turns else True
    at_lower, at_upper = (q <= lower + 1e-9) & bounded, (q >= upper - 1e-9) & bounded
    if at_lower.any() or at_upper.any():
        g = (j * err[:, :, None]).sum(axis=1)  # J^T e (no einsum: see rotation_log)
        blocked = (at_lower & (g < 0)) | (at_upper & (g > 0))
        j = j * ~blocked[:, None, :]
    dq = dls_step(j, err, lam2, eye)
    scale = np.maximum(1.0, np.abs(dq).max(axis=1) / ctx.config.max_step)
    q = q + dq / scale[:, None]
    if turns:
        # the same placement of the arm, a turn back within the limits (a clamp there left
        # rows stuck against +-2 pi: 4 of a UR5 pose call's 24 starts, refined 8 steps for
        # nothing, measured with stall checks from step 8)
        whole = 2 * np.pi * robot.periodic
        q += whole * (q < lower) - whole * (q > upper)
    return np.minimum(np.maximum(q, lower), upper)  # np.clip, without its wrapper's 5 us


def refine(ctx: Context, q: np.ndarray, goal: Goal, deadline: Optional[float] = None,
           iterations: Optional[int] = None, prune: bool = False,
           enough: Optional[int] = None) -> Refined:
    """Batched damped least squares from ``q`` (M, n) towards ``goal``, within the limits.

    With ``prune``, at the iterations in ``config.prune_at`` a candidate closer than
    ``config.prune_radius`` to one with a lower error (converged ones included) stops there:
    both are heading for the same solution, which the final duplicate removal would keep only
    once. Its row is returned as it was when it stopped. With ``enough``, it stops as soon as
    ``enough`` distinct rows meet the tolerances (the others are returned where they are, with
    their errors). A periodic joint stepping past a limit is turned back by 2 pi (the same
    placement; see :func:`limited_step`).

    Args:
        ctx: the solver's parts.
        q: starting configurations (M, n) [rad].
        goal: the target.
        deadline: a ``time.perf_counter()`` value after which no iteration starts.
        iterations: most iterations (default: ``config.refine_iterations``).
        prune: merge candidates heading for the same solution.
        enough: stop once this many distinct candidates are exact.
    """
    cfg = ctx.config
    pos, rot = goal.position, goal.rotation
    q = q.copy()
    n = len(q)
    rows = 3 if rot is None else 6
    lam2 = cfg.damping ** 2
    eye = np.eye(rows)
    active = np.ones(n, dtype=bool)
    given_up = np.zeros(n, dtype=bool)
    perr_all, oerr_all = np.full(n, np.inf), np.zeros(n)
    stale = np.ones(n, dtype=bool)  # rows moved since their errors were computed
    score = np.full(n, np.inf)  # latest error of each row, to choose between neighbours
    window = cfg.stall_window
    history = np.full((window, n), np.inf)  # errors of the last ``window`` iterations
    exact = np.zeros(n, dtype=bool)
    cut_short = False
    roll_free = ctx.ignores_last(goal.kind)
    for it in range(iterations or cfg.refine_iterations):
        if prune and it in cfg.prune_at:
            alive = np.flatnonzero(~given_up)
            order = alive[np.argsort(score[alive], kind='stable')]
            keep = distinct_mask(q[order], cfg.prune_radius, ctx.ignores_last(goal.kind))
            active[order[~keep]] = False
        idx = np.flatnonzero(active)
        if len(idx) == 0:
            break
        if deadline is not None and time.perf_counter() > deadline:
            cut_short = True
            break
        p, r, jac = ctx.robot.jacobian_loop(q[idx], ctx.data)
        err = pos - p
        perr = np.sqrt((err * err).sum(1))
        done = perr < cfg.position_tolerance * 0.5
        stuck = perr > 10 * cfg.position_tolerance
        if rot is not None:
            rot_err = rotation_log(rot @ r.transpose(0, 2, 1))
            oerr = np.sqrt((rot_err * rot_err).sum(1))
            err = np.concatenate([err, rot_err], axis=1)
            done &= oerr < cfg.orientation_tolerance * 0.5
            stuck |= oerr > 10 * cfg.orientation_tolerance
            oerr_all[idx] = oerr
            score[idx] = pose_score(perr, oerr)
        else:
            score[idx] = perr
        perr_all[idx] = perr
        stale[idx] = False
        if enough and done.any():
            exact[idx[done]] = True
            found = np.flatnonzero(exact)
            if len(found) >= enough and (
                    distinct_mask(q[found], cfg.distinct_threshold, roll_free).sum() >= enough):
                break
        if window and it >= max(window, cfg.stall_after):
            # hardly closer than ``window`` iterations ago: stalled (near a solution the steps
            # converge fast; a row that does not is held by a joint limit or a singularity)
            stalled = ~done & (score[idx] > cfg.stall_ratio * history[it % window, idx])
        else:
            stalled = None
        if window:
            history[it % window, idx] = score[idx]
        if it >= cfg.give_up_after or (stalled is not None and stalled.any()):
            # far from the goal this late: a local minimum or a joint limit, not worth more
            if it < cfg.give_up_after:
                stuck = stalled
            elif stalled is not None:
                stuck = stuck | stalled
            given_up[idx[stuck & ~done]] = True
            done |= stuck
        if done.any():
            active[idx[done]] = False
            go = ~done
            if not go.any():
                continue
            idx, jac, err = idx[go], jac[go], err[go]
        q[idx] = limited_step(ctx, q[idx], jac[:, :rows], err, lam2, eye, turn=True)
        stale[idx] = True
    moved = np.flatnonzero(stale)
    if len(moved):
        perr_all[moved], oerr_all[moved] = errors(ctx, q[moved], goal)
    return Refined(q, perr_all, oerr_all, cut_short)


def follow(ctx: Context, q: np.ndarray, start: Evaluation, goal: Goal, iterations: int,
           deadline: Optional[float] = None) -> Tuple[np.ndarray, np.ndarray, Evaluation]:
    """Configurations near ``goal`` refined onto it, carrying their evaluations: a lean refine.

    For a path's tracks, each a small step from the next waypoint: no merging, stalling or
    giving up to watch for. Each iteration takes the rows' errors from their evaluation; the
    rows within the tolerances stop, the others take a :func:`limited_step` and are evaluated
    again (one Pinocchio call per row, whose Jacobian the next waypoint's first step uses).
    The first step is taken on the Jacobian extrapolated to the step's midpoint
    (``jac + djac / 2``): along a path the residual left is then of third order, within the
    tolerances after one step nearly always (one evaluation per waypoint), where a plain
    Newton step leaves a second-order one.

    Args:
        ctx: the solver's parts.
        q: configurations (M, n) [rad].
        start: their evaluation.
        goal: the target: one, or one per row (``position`` (M, 3), ``rotation`` (M, 3, 3)).
        iterations: most steps per row; rows not exact after them are dropped.
        deadline: a ``time.perf_counter()`` value after which no step starts.

    Returns:
        the indices of the exact rows (K,), in order, the rows (K, n) and their evaluation.
    """
    cfg = ctx.config
    dims = 3 if goal.rotation is None else 6
    lam2, eye = cfg.damping ** 2, np.eye(dims)
    tol2, otol2 = cfg.position_tolerance ** 2, cfg.orientation_tolerance ** 2
    # the rows still going (``act``) and theirs; finished rows go to ``parts``
    act, aq, ap, ar, aj, dj = np.arange(len(q)), q, start.p, start.r, start.jac, start.djac
    pos, rot = goal.position, goal.rotation
    per_row = pos.ndim == 2
    parts = []
    for it in range(iterations + 1):
        err = pos - ap
        ok = np.einsum('ij,ij->i', err, err) <= tol2
        if rot is not None:
            rot_err = rotation_log(rot @ ar.transpose(0, 2, 1))
            ok &= np.einsum('ij,ij->i', rot_err, rot_err) <= otol2
            err = np.concatenate([err, rot_err], axis=1)
        if ok.all():
            parts.append((act, aq, ap, ar, aj, it > 0))
            break
        if ok.any():
            parts.append((act[ok], aq[ok], ap[ok], ar[ok], aj[ok], it > 0))
            go = ~ok
            act, aq, ap, ar, aj, dj, err = act[go], aq[go], ap[go], ar[go], aj[go], dj[go], err[go]
            if per_row:
                pos, rot = pos[go], None if rot is None else rot[go]
        if it == iterations or (deadline is not None and time.perf_counter() > deadline):
            break
        j = aj[:, :dims] + 0.5 * dj[:, :dims] if it == 0 else aj[:, :dims]
        aq = limited_step(ctx, aq, j, err, lam2, eye)
        ap, ar, aj = ctx.robot.jacobian_loop(aq, ctx.data)
    if not parts:
        rows = np.empty(0, dtype=int)
        return rows, q[:0], start.rows(rows)
    if len(parts) == 1:
        rows, qf, pf, rf, jf, _ = parts[0]
    else:
        order = np.concatenate([part[0] for part in parts])
        sort = np.argsort(order, kind='stable')
        rows, qf, pf, rf, jf = (np.concatenate([part[k] for part in parts])[sort]
                                for k in range(5))
    djac = jf - start.jac[rows]
    if not parts[0][5]:  # rows exact where they were keep their last change
        first = np.isin(rows, parts[0][0])
        djac[first] = start.djac[rows[first]]
    return rows, qf, Evaluation(pf, rf, jf, djac)
