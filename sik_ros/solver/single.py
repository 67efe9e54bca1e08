"""One solution with the default ranking: the first exact, free answer of a few starts.

A caller asking for one solution ranked by the default objective gets the first exact answer
free of self-collision (as TRAC-IK's first answer), refined from the seed, then for a pose goal
of an arm with more than six joints from the position model's postures that had the goal's
orientation (:func:`single_starts`, :func:`from_starts`). The stages of
:mod:`sik_ros.solver.pipeline` run only when these give none. Also the helpers both share:
how many oriented postures a call takes, where periodic joints take their turns, and the
posture indices filled in when read.
"""

import functools
from typing import List, Optional, Sequence

import numpy as np

from sik_ros.deadline import Deadline
from sik_ros.kinematics.collision import Obstacle
from sik_ros.kinematics.periodic import nearest_turns
from sik_ros.solver.batch import Candidates
from sik_ros.solver.candidates import oriented_postures
from sik_ros.solver.codec import encode
from sik_ros.solver.config import ORIENTED_MIN, SolverConfig
from sik_ros.solver.context import Context, Goal, POSE
from sik_ros.solver.explore import unindexed
from sik_ros.solver.ranking import rank
from sik_ros.solver.refine import refine
from sik_ros.solver.results import IKResult, PendingIndices, Solution
from sik_ros.solver.scores import converged


def oriented_count(cfg: SolverConfig, num: int) -> int:
    """Oriented postures a pose goal asking for ``num`` solutions starts from."""
    return min(cfg.oriented_candidates, max(ORIENTED_MIN, 2 * num))


def fill_indices(ctx: Context, goal: Goal, sols: List[Solution]) -> None:
    """Posture indices of solutions that came without one: the encoding of their q.

    Encoded when first read (:class:`PendingIndices`), all of them in one call.
    """
    if not sols:
        return
    # one check over all of them, not one per solution
    todo = [sols[i] for i in np.flatnonzero(
        np.isnan(np.array([s.posture_index for s in sols])).any(axis=1))]
    if todo:
        PendingIndices(todo, functools.partial(encode, ctx, goal))


def turns_centre(ctx: Context, q_seed: Optional[np.ndarray]) -> np.ndarray:
    """Where periodic joints take their turns: the seed, else the middle of the ranges [rad]."""
    return q_seed if q_seed is not None else (ctx.robot.lower + ctx.robot.upper) / 2


def from_starts(ctx: Context, goal: Goal, starts: np.ndarray, q_seed: Optional[np.ndarray],
                obstacles: Sequence[Obstacle], deadline: Deadline) -> Optional[IKResult]:
    """One solution: the first of ``starts`` refined onto the goal that is exact and free.

    None when none is. The single-solution path: with a seed (default ranking), a solution
    ranked by its distance to the seed is nearly always the seed's own posture refined onto
    the goal; without one, the first exact solution is as good as any (as TRAC-IK's first
    answer), and for a pose goal the position model's postures that had the goal's
    orientation reach it first. The stages of :func:`solve` only when this gives nothing.
    Periodic joints take the turns nearest the seed (or the middle of their ranges).
    """
    cut = False
    while len(starts) and not deadline.expired():
        r = refine(ctx, starts, goal, deadline, enough=1)
        cut = cut or r.cut_short
        exact = np.flatnonzero(converged(r.perr, r.oerr, goal.kind, ctx.config))
        if len(exact) == 0:
            return None
        # rows are refined in order and stop at the first exact one: it alone is exact
        first = exact[0]
        q = r.q[first:first + 1]
        if ctx.robot.periodic.any():
            q = nearest_turns(ctx.robot, q, turns_centre(ctx, q_seed))
        starts = starts[first + 1:]  # the starts after it, not yet refined
        selfc = ctx.checker.self_collision(q)
        if selfc[0]:
            continue
        c = Candidates(q, unindexed(q, ctx.models[goal.kind].table.indices.shape[1]),
                       r.perr[exact[:1]], r.oerr[exact[:1]], np.ones(1, dtype=bool))
        sols = rank(ctx, c, q_seed, obstacles, None, limit=1, deadline=deadline,
                    self_collision=selfc)
        if sols and not sols[0].in_collision:
            fill_indices(ctx, goal, sols)
            sols[0].family = 0  # one exact solution: one family known
            return IKResult(True, sols, goal.kind, cut, num_families=1)
    return None


def single_starts(ctx: Context, goal: Goal, q_seed: Optional[np.ndarray],
                  obstacles: Sequence[Obstacle]) -> np.ndarray:
    """The starts of :func:`from_starts` for one solution with the default ranking, (M, n).

    The seed first; then, for a pose goal of an arm with more than six joints near the data
    and without obstacles (which need every start refined), the position model's postures
    that had the goal's orientation: the starts the stages of :func:`solve` would refine
    first, the seed having failed. Empty: the full stages.
    """
    seed = np.empty((0, ctx.robot.dof)) if q_seed is None else q_seed[None]
    if goal.kind != POSE or ctx.robot.dof <= 6 or obstacles or \
            not ctx.models[goal.kind].table.within(goal.position, ctx.config.reach_margin):
        return seed
    return np.concatenate([seed, oriented_postures(ctx, goal, oriented_count(ctx.config, 1))])
