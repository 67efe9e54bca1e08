"""More solutions than the table's postures give: branch starts, restarts, the self-motion walk.

:func:`seed_starts` (from the bundle's seed table) or :func:`branch_starts` (uniform random)
give the isolated pose solutions of arms with six joints or fewer a start per branch
(:mod:`sik_ros.solver.families.branches` gives starts for the branches they miss).
:func:`restart` starts again from perturbed and random configurations when no candidate
converged. :func:`walk` moves found pose solutions along the null space of their Jacobian (the
self-motion manifold of a redundant arm at a 6-d pose) and refines them back onto the goal, for
distinct exact solutions the table did not give. :func:`periodic_equivalents` adds the 2 pi
turns of periodic joints (:mod:`sik_ros.kinematics.periodic`).
"""

from typing import Tuple
import zlib

import numpy as np

from sik_ros.deadline import Deadline
from sik_ros.kernels.chain import null_directions
from sik_ros.kernels.selfmotion import step_rows
from sik_ros.kinematics.periodic import equivalents
from sik_ros.solver.batch import Candidates
from sik_ros.solver.config import EQUIVALENTS_PER_SOLUTION, RESTART_SPREAD, RESTARTS
from sik_ros.solver.context import Context, Goal
from sik_ros.solver.refine import refine
from sik_ros.solver.scores import assess, distinct_mask, pose_score
from sik_ros.tables.point_sets import pairwise_distances
from sik_ros.tables.seed_table import SeedTable


def unindexed(q: np.ndarray, latent: int) -> np.ndarray:
    """Posture indices of new candidates: NaN, encoded once ranked."""
    return np.full((len(q), latent), np.nan)


def restart(ctx: Context, c: Candidates, goal: Goal, deadline: Deadline, keep: int = RESTARTS,
            stream: int = 0) -> Tuple[Candidates, bool]:
    """``c`` and new candidates from perturbed copies of its best and from random ones.

    The perturbations come from a random stream fixed per target (and ``stream``, for rounds
    that should draw anew), so answers stay deterministic.

    Returns:
        all candidates, and whether the deadline cut the refinement short.
    """
    robot = ctx.robot
    best = np.argsort(pose_score(c.perr, c.oerr))[:keep]
    key = zlib.crc32(goal.position.tobytes())
    rng = np.random.default_rng(key if stream == 0 else [key, stream])
    span = robot.upper - robot.lower
    spread = rng.normal(0, RESTART_SPREAD, (len(best), c.q.shape[1]))
    q2 = np.concatenate([c.q[best] + spread * span,
                         rng.uniform(robot.lower, robot.upper, (keep, c.q.shape[1]))])
    r = refine(ctx, np.clip(q2, robot.lower, robot.upper), goal, deadline)
    new = assess(r.q, unindexed(r.q, c.z.shape[1]), r.perr, r.oerr, goal.kind, ctx.config)
    return Candidates.concat(c, new), r.cut_short


def branch_starts(ctx: Context, goal: Goal, count: int, latent: int) -> Candidates:
    """``count`` starts drawn uniformly in joint space, to be refined with the model's own.

    A pose of an arm with six joints or fewer has isolated solutions (up to 8 branches for a
    6-joint wrist-partitioned arm): no self-motion leads from one to another, and the model's
    candidates seldom cover them all, so random starts look for the rest, as TRAC-IK's random
    restarts do. They join the model's candidates in one refinement (one pass of the batched
    loop, and neighbours heading for one solution are merged across both). The draws are
    fixed per target (deterministic answers).
    """
    robot = ctx.robot
    rng = np.random.default_rng(zlib.crc32(goal.position.tobytes()) + 1)
    q = rng.uniform(robot.lower, robot.upper, (max(count, 0), robot.dof))
    inf = np.full(len(q), np.inf)
    return Candidates(q, unindexed(q, latent), inf, inf, np.zeros(len(q), dtype=bool))


def seed_starts(ctx: Context, goal: Goal, seeds: SeedTable, count: int,
                latent: int) -> Candidates:
    """Up to ``count`` dataset configurations whose tips were near the goal pose, far apart.

    Isolated solutions each need a start of their own; the bundle's seed table
    (:mod:`sik_ros.tables.seed_table`) has configurations near the goal on every branch the data
    covers, a few refinement steps from their solutions, where uniform random starts
    (:func:`branch_starts`) land in the larger branches' basins again and again.
    """
    q = seeds.starts(goal.position, goal.quaternion, count, ctx.config.seed_neighbours)
    inf = np.full(len(q), np.inf)
    return Candidates(q, unindexed(q, latent), inf, inf, np.zeros(len(q), dtype=bool))


def periodic_equivalents(ctx: Context, c: Candidates,
                         per_solution: int = EQUIVALENTS_PER_SOLUTION,
                         ignore_last: bool = False) -> Candidates:
    """``c`` and, after each row, its equivalents with periodic joints turned by +-2 pi.

    A periodic joint's q and q +- 2 pi place the arm alike; each equivalent within the joint
    limits is a further solution (cable wrap, distance to the current state). Per row, at most
    ``per_solution`` of them: one joint turned, then two
    (:func:`sik_ros.kinematics.periodic.equivalents`).
    With ``ignore_last`` (position goals whose last joint only turns the tool: postures told
    apart without it) the last joint is never turned: that would give the same posture again.
    """
    robot = ctx.robot
    turnable = tuple(bool(p) for p in robot.periodic)
    if ignore_last:
        turnable = turnable[:-1] + (False,)
    if not any(turnable) or len(c) == 0:
        return c
    rows, q = equivalents(robot, c.q, turnable, per_solution)
    out = c.take(rows)
    return Candidates(q, out.z, out.perr, out.oerr, out.exact)


def null_space(ctx: Context, q: np.ndarray) -> np.ndarray:
    """Unit vectors (M, n) in the null spaces of the Jacobians at ``q`` (M, n).

    Of a 7-joint arm's, from the signed minors (compiled); of other arms, and where a
    Jacobian is nearly singular, the right singular vector of its smallest singular value.
    """
    _, _, jac = ctx.robot.jacobian_loop(q, ctx.data)
    nvec = np.empty(q.shape)
    ok = np.zeros(len(q), dtype=bool)
    if q.shape[1] == 7 and jac.shape[1] == 6:
        ok = null_directions(jac, nvec)
    if not ok.all():
        nvec[~ok] = np.linalg.svd(jac[~ok])[2][:, -1]
    return nvec


def walk(ctx: Context, c: Candidates, goal: Goal, deadline: Deadline,
         need: int) -> Candidates:
    """``c`` and the distinct exact solutions found along the self-motion of its exact ones.

    Each round moves every frontier solution ``walk_step`` [rad] along the unit null-space
    vector of its Jacobian (both ways from the first ones, then onwards), refines it for at
    most ``walk_iterations`` iterations, and keeps the new exact solutions at least
    ``distinct_threshold`` from every found one; they are the next frontier. Stops after
    ``walk_rounds`` rounds, once ``need`` distinct solutions are found, or when a round finds
    none.
    """
    cfg = ctx.config
    if not c.exact.any():
        return c
    rows = np.flatnonzero(c.exact)
    rows = rows[np.argsort(pose_score(c.perr[rows], c.oerr[rows]), kind='stable')]
    roll_free = ctx.ignores_last(goal.kind)
    found = c.q[rows[distinct_mask(c.q[rows], cfg.distinct_threshold, roll_free)]]
    if len(found) >= need:
        return c
    frontier, heading = found, None
    new = []
    for _ in range(cfg.walk_rounds):
        nvec = null_space(ctx, frontier)
        first = heading is None
        if first:
            nvec = np.concatenate([nvec, -nvec])
            frontier = np.concatenate([frontier, frontier])
            heading = np.empty_like(nvec)
        start = np.empty_like(frontier)
        step_rows(frontier, nvec, heading, first, cfg.walk_step, ctx.robot.lower,
                  ctx.robot.upper, start)
        r = refine(ctx, start, goal, deadline, cfg.walk_iterations)
        step = assess(r.q, unindexed(r.q, c.z.shape[1]), r.perr, r.oerr, goal.kind, cfg)
        pick = np.empty(0, dtype=int)
        if step.exact.any():
            far_enough = pairwise_distances(step.q[step.exact], found).min(axis=1) \
                >= cfg.distinct_threshold
            pick = np.flatnonzero(step.exact)[far_enough]
            pick = pick[distinct_mask(step.q[pick], cfg.distinct_threshold, roll_free)]
        if len(pick) == 0:
            break
        new.append(step.take(pick))
        found = np.concatenate([found, step.q[pick]])
        frontier, heading = step.q[pick], nvec[pick]
        if len(found) >= need:
            break
    return Candidates.concat(c, *new) if new else c
