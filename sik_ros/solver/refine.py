"""Refinement: damped least squares towards a goal, within the joint limits (compiled).

The starts are handed to :func:`sik_ros.kernels.dls.refine_rows`, which refines them row by row:
steps ``J^T (J J^T + lambda^2 I)^-1 e`` on the chain's Jacobian; joints at a limit that the
descent direction pushes further out leave the step (active set). A row stops when it reaches
the goal, stalls or stays far from it, heads for the same solution as an earlier, better row,
or at the deadline; all stop once enough distinct rows are exact (see
:class:`~sik_ros.solver.config.SolverConfig`). :func:`follow` does the same for a path's tracks
(:func:`sik_ros.kernels.dls.follow_rows`).
"""

from dataclasses import dataclass
import functools
import math
from typing import Optional, Tuple

import numpy as np

from sik_ros.deadline import Deadline, NO_DEADLINE
from sik_ros.kernels import as_arg, follow_rows, refine_rows
from sik_ros.kernels.dls import goal_errors_rows, INTS, REALS
from sik_ros.kernels.follow import FOLLOW
from sik_ros.solver.config import (CONVERGE_FACTOR, GIVE_UP_FACTOR, ORIENTATION_WEIGHT,
                                   SolverConfig)
from sik_ros.solver.context import Context, Goal

#: The rotation handed to the kernels with a position goal (not read).
NO_ROTATION = np.eye(3)
#: Where the deadline is in :func:`refine_rows`'s real settings.
DEADLINE = REALS.index('deadline')
FOLLOW_DEADLINE = FOLLOW.index('deadline')


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
    """Position errors [m] and orientation errors [rad] (zeros for position goals), (M,).

    The measure the refinement reports (:func:`sik_ros.kernels.dls.goal_errors_rows`).
    """
    q = as_arg(q)
    perr, oerr = np.empty(len(q)), np.empty(len(q))
    pose = goal.rotation is not None
    goal_errors_rows(ctx.robot.frames, q, as_arg(goal.position),
                     as_arg(goal.rotation) if pose else NO_ROTATION, pose, perr, oerr)
    return perr, oerr


def refine(ctx: Context, q: np.ndarray, goal: Goal, deadline: Deadline = NO_DEADLINE,
           iterations: Optional[int] = None, prune: bool = False,
           enough: Optional[int] = None,
           limits: Optional[Tuple[np.ndarray, np.ndarray]] = None) -> Refined:
    """Damped least squares from each row of ``q`` (M, n) towards ``goal``, within the limits.

    Rows are refined one after the other, in order. With ``prune``, at the iterations in
    ``config.prune_at`` a row closer than ``config.prune_radius`` to an earlier one with a
    lower error (converged ones included) stops there: both are heading for the same solution,
    which the final duplicate removal would keep only once. Its row is returned as it was when
    it stopped. With ``enough``, refinement stops as soon as ``enough`` distinct rows meet the
    tolerances (the rows after them are returned as they were, with their errors). A periodic
    joint stepping past a limit is turned back by 2 pi (the same placement, where a clamp would
    hold it against the limit).

    Args:
        ctx: the solver's parts.
        q: starting configurations (M, n) [rad].
        goal: the target.
        deadline: after it no iteration starts.
        iterations: most iterations per row (default: ``config.refine_iterations``).
        prune: stop rows heading for the same solution as an earlier, better one.
        enough: stop once this many distinct rows are exact.
        limits: lower and upper limits (n,) [rad] in place of the arm's (a joint held at a
            value: both its limits that value).
    """
    cfg, robot = ctx.config, ctx.robot
    q = np.array(q, dtype=float, order='C')
    m = len(q)
    perr, oerr, status = np.empty(m), np.empty(m), np.empty(m, dtype=np.int8)
    pose = goal.rotation is not None
    reals, ints = kernel_settings(cfg, iterations or cfg.refine_iterations, enough or 0,
                                  bool(prune), ctx.ignores_last(goal.kind), pose)
    reals = reals.copy()
    reals[DEADLINE] = deadline.at
    lower, upper = (robot.lower, robot.upper) if limits is None else limits
    cut = refine_rows(robot.frames, lower, upper, robot.periodic, q,
                      as_arg(goal.position), as_arg(goal.rotation) if pose else NO_ROTATION,
                      reals, ints, perr, oerr, status)
    return Refined(q, perr, oerr, bool(cut))


@functools.lru_cache(maxsize=256)
def kernel_settings(cfg: SolverConfig, iterations: int, enough: int, prune: bool,
                    roll_free: bool, pose: bool) -> Tuple[np.ndarray, np.ndarray]:
    """:func:`refine_rows`'s settings arrays (its ``deadline`` left infinite), made once each.

    ``ints`` holds the named values, then ``config.prune_at``
    (:data:`~sik_ros.kernels.dls.PRUNE_AT`).

    Shared: not to be written (a caller copies ``reals`` to set its deadline; the kernels
    take writeable arrays only).
    """
    settings = {'position_tolerance': cfg.position_tolerance,
                'orientation_tolerance': cfg.orientation_tolerance,
                'damping2': cfg.damping ** 2, 'max_step': cfg.max_step,
                'stall_ratio': cfg.stall_ratio, 'prune_radius': cfg.prune_radius,
                'distinct_threshold': cfg.distinct_threshold,
                'deadline': math.inf, 'orientation_weight': ORIENTATION_WEIGHT,
                'converge_factor': CONVERGE_FACTOR, 'give_up_factor': GIVE_UP_FACTOR,
                'iterations': iterations, 'stall_window': cfg.stall_window,
                'stall_after': cfg.stall_after, 'give_up_after': cfg.give_up_after,
                'enough': enough, 'prune': int(prune), 'roll_free': int(roll_free),
                'pose': int(pose)}
    return (np.array([settings[k] for k in REALS], dtype=float),
            np.array([settings[k] for k in INTS] + list(cfg.prune_at), dtype=np.int64))


@functools.lru_cache(maxsize=256)
def follow_settings(cfg: SolverConfig, iterations: int, pose: bool,
                    per_row: bool) -> np.ndarray:
    """:func:`follow_rows`'s settings (:data:`~sik_ros.kernels.follow.FOLLOW`), made once each.

    Its deadline left infinite; shared: a caller copies it to set its deadline.
    """
    values = {'tol2': cfg.position_tolerance ** 2, 'otol2': cfg.orientation_tolerance ** 2,
              'damping2': cfg.damping ** 2, 'max_step': cfg.max_step,
              'iterations': iterations, 'deadline': math.inf, 'pose': pose, 'per_row': per_row}
    return np.array([values[k] for k in FOLLOW], dtype=float)


def follow(ctx: Context, q: np.ndarray, start: Evaluation, goal: Goal, iterations: int,
           deadline: Deadline = NO_DEADLINE) -> Tuple[np.ndarray, np.ndarray, Evaluation]:
    """Configurations near ``goal`` refined onto it, carrying their evaluations: a lean refine.

    For a path's tracks, each a small step from the next waypoint: no merging, stalling or
    giving up to watch for. Each row's error comes from its evaluation; a row within the
    tolerances stops, the others take a step (no turns of periodic joints: a path's joint must
    not jump) and are evaluated again, whose Jacobian the next waypoint's first step uses.
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
        deadline: after it no step starts.

    Returns:
        the indices of the exact rows (K,), in order, the rows (K, n) and their evaluation.
    """
    cfg, robot = ctx.config, ctx.robot
    m = len(q)
    q = np.array(q, dtype=float, order='C')
    p, r, jac = (np.array(a, dtype=float, order='C') for a in (start.p, start.r, start.jac))
    pose = goal.rotation is not None
    pos = as_arg(np.reshape(goal.position, (-1, 3)))
    rot = as_arg(np.reshape(goal.rotation, (-1, 3, 3))) if pose else NO_ROTATION[None]
    outcome = np.empty((2, m), dtype=np.int64)
    settings = follow_settings(cfg, iterations, pose, goal.position.ndim == 2).copy()
    settings[FOLLOW_DEADLINE] = deadline.at
    follow_rows(robot.frames, robot.lower, robot.upper, q, p, r, jac, as_arg(start.djac), pos,
                rot, settings, outcome)
    ok, steps = outcome[0] != 0, outcome[1]
    rows = np.flatnonzero(ok)
    jac = jac[rows]
    # a row exact where it was keeps its last change
    djac = np.where(steps[rows, None, None] > 0, jac - start.jac[rows], start.djac[rows])
    return rows, q[rows], Evaluation(p[rows], r[rows], jac, djac)
