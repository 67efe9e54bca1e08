"""Every branch of an isolated pose goal, ranked by the default objective: the lean path.

An arm with six joints or fewer reaches a pose on a few isolated branches (one or two for the
SO-100 and the Z1 within their limits, up to eight for a UR5). With the bundle's seed table, no
seed, no obstacles and the default objective, a call is: the seed table's starts near the goal
pose, refined (with starts for the branches they missed, and the exact ones polished onto their
solutions: :mod:`sik_ros.solver.families.branches`); the exact ones, one per posture; ranked by
closeness to the joint limits, self-collision checked in that order. :func:`every_branch` does
just that in a few compiled calls (:func:`~sik_ros.kernels.sets.exact_by_margin` for the last
steps) and the collision checks, where the general stages of :mod:`sik_ros.solver.pipeline`
carry candidate batches through some thirty NumPy calls this case does not need. Its answers
are the general stages' (``bench/answers.py`` compares them); arms with periodic joints take
the general ranking (2 pi equivalents), and a goal no start reaches exactly goes on to the
general stages' restarts with the starts already refined.
"""

import functools
from typing import Optional, Tuple

import numpy as np

from sik_ros.deadline import Deadline
from sik_ros.kernels.sets import exact_by_margin
from sik_ros.solver.batch import Candidates
from sik_ros.solver.codec import encode
from sik_ros.solver.config import ORIENTATION_WEIGHT
from sik_ros.solver.context import Context, Goal
from sik_ros.solver.explore import unindexed
from sik_ros.solver.families.branches import other_branches, polished
from sik_ros.solver.families.membership import number, same_solution
from sik_ros.solver.refine import refine, Refined
from sik_ros.solver.results import IKResult, PendingIndices, Solution, tiers
from sik_ros.solver.scores import assess
from sik_ros.tables.seed_table import SeedTable

#: What :func:`every_branch` returns: the answer, or None and the refined starts as candidates
#: for the general stages; and whether the deadline cut refinement short.
Branches = Tuple[Optional[IKResult], Optional[Candidates], bool]


def every_branch(ctx: Context, goal: Goal, seeds: SeedTable, num: int,
                 enough: Optional[int], deadline: Deadline) -> Branches:
    """The best ``num`` branches from the seed table's starts near a pose goal.

    The starts are refined (all of them; with ``enough``, until as many distinct ones are
    exact; without, starts for the branches they missed follow and the exact rows are polished
    onto their solutions: :func:`~sik_ros.solver.families.branches.other_branches`,
    :func:`~sik_ros.solver.families.branches.polished`). The exact ones, taken by their goal
    error, one per posture
    (``distinct_threshold`` apart), are ranked by
    :class:`~sik_ros.solver.objectives.JointLimitMargin`,
    those free of self-collision first, each checked in that order until ``num`` free ones are
    found (the rest, not checked, are reported free): :func:`~sik_ros.solver.ranking.rank`'s
    order for these candidates.
    """
    cfg, robot = ctx.config, ctx.robot
    q = seeds.starts(goal.position, goal.quaternion, cfg.seed_starts, cfg.seed_neighbours)
    r = refine(ctx, q, goal, deadline, enough=enough)
    if enough is None:  # every branch: starts for those the table's nearest rows missed
        r = polished(ctx, goal, seeds.signs, other_branches(ctx, goal, seeds, r, deadline))
    keep = np.empty(0, dtype=np.int64)
    if not robot.periodic.any():
        keep, cost = exact_by_margin(r.q, r.perr, r.oerr, cfg.position_tolerance,
                                     cfg.orientation_tolerance, ORIENTATION_WEIGHT,
                                     same_solution(ctx, goal.kind), robot.lower, robot.upper)
    if not len(keep):
        return None, as_candidates(ctx, goal, r), r.cut_short
    selfc = np.zeros(len(keep), dtype=bool)
    free = 0
    for i, row in enumerate(keep):
        if free >= num or deadline.expired():
            break
        selfc[i] = ctx.checker.self_collision(r.q[row][None])[0]
        free += not selfc[i]
    unknown = np.full(ctx.models[goal.kind].table.indices.shape[1], np.nan, dtype=np.float32)
    tier = tiers(selfc, np.zeros(len(keep), dtype=bool))  # every row here is exact
    # distinct exact rows of isolated solutions without periodic joints: each its own branch
    sols = [Solution(q=r.q[keep[i]].copy(), position_error=float(r.perr[keep[i]]),
                     orientation_error=float(r.oerr[keep[i]]), posture_index=unknown.copy(),
                     score=float(cost[i]), self_collision=bool(selfc[i]), converged=True,
                     tier=int(tier[i]), family=int(keep[i]))
            for i in np.argsort(tier, kind='stable')[:num]]
    PendingIndices(sols, functools.partial(encode, ctx, goal))  # encoded when first read
    found = number(sols, keep)
    return IKResult(True, sols, goal.kind, r.cut_short, num_families=found), None, r.cut_short


def as_candidates(ctx: Context, goal: Goal, r: Refined) -> Candidates:
    """The general stages' batch of refined starts (no posture indices yet)."""
    latent = ctx.models[goal.kind].table.indices.shape[1]
    return assess(r.q, unindexed(r.q, latent), r.perr, r.oerr, goal.kind, ctx.config)
