"""More solutions when the first refinement is not enough: restarts and the self-motion walk.

:func:`restart` starts again from perturbed and random configurations when no candidate
converged. :func:`walk` moves found pose solutions along the null space of their Jacobian (the
self-motion manifold of a redundant arm at a 6-d pose) and refines them back onto the goal, for
distinct exact solutions the table did not give.
"""

from typing import Tuple
import zlib

import numpy as np
from scipy.spatial.distance import cdist

from sik_ros.solver.batch import Candidates
from sik_ros.solver.context import Context, Goal
from sik_ros.solver.ranking import assess, distinct_mask, pose_score
from sik_ros.solver.refine import refine


def _unindexed(q: np.ndarray, latent: int) -> np.ndarray:
    """Posture indices of new candidates: NaN, encoded once ranked."""
    return np.full((len(q), latent), np.nan)


def restart(ctx: Context, c: Candidates, goal: Goal, deadline, keep: int = 8
            ) -> Tuple[Candidates, bool]:
    """``c`` and new candidates from perturbed copies of its best and from random ones.

    The perturbations come from a random stream fixed per target, so answers stay
    deterministic.

    Returns:
        all candidates, and whether the deadline cut the refinement short.
    """
    robot = ctx.robot
    best = np.argsort(pose_score(c.perr, c.oerr))[:keep]
    rng = np.random.default_rng(zlib.crc32(goal.position.tobytes()))
    span = robot.upper - robot.lower
    q2 = np.concatenate([c.q[best] + rng.normal(0, 0.15, (len(best), c.q.shape[1])) * span,
                         rng.uniform(robot.lower, robot.upper, (keep, c.q.shape[1]))])
    r = refine(ctx, np.clip(q2, robot.lower, robot.upper), goal, deadline)
    new = assess(r.q, _unindexed(r.q, c.z.shape[1]), r.perr, r.oerr, goal.kind, ctx.config)
    return Candidates.concat(c, new), r.cut_short


def periodic_equivalents(ctx: Context, c: Candidates, per_solution: int = 16) -> Candidates:
    """``c`` and, after each row, its equivalents with periodic joints turned by +-2 pi.

    A periodic joint's q and q +- 2 pi place the arm alike; each equivalent within the joint
    limits is a further solution (cable wrap, distance to the current state). Per row, at most
    ``per_solution`` of them, fewest joints turned first.
    """
    robot = ctx.robot
    turns = np.flatnonzero(robot.periodic)
    if len(turns) == 0 or len(c) == 0:
        return c
    rows, shifted = [], []
    for i, q in enumerate(c.q):
        options = [[0.0] + [s for s in (2 * np.pi, -2 * np.pi)
                            if robot.lower[j] - 1e-9 <= q[j] + s <= robot.upper[j] + 1e-9]
                   for j in turns]
        combos = np.array(np.meshgrid(*options, indexing='ij')).reshape(len(turns), -1).T
        combos = combos[np.argsort((combos != 0).sum(1), kind='stable')][:per_solution + 1]
        for shift in combos:
            qs = q.copy()
            qs[turns] += shift
            rows.append(i)
            shifted.append(np.clip(qs, robot.lower, robot.upper))
    out = c.take(np.array(rows))
    return Candidates(np.array(shifted), out.z, out.perr, out.oerr, out.exact)


def walk(ctx: Context, c: Candidates, goal: Goal, deadline, need: int) -> Candidates:
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
        _, _, jac = ctx.robot.jacobian_loop(frontier, ctx.data)
        nvec = np.linalg.svd(jac)[2][:, -1]  # unit vectors spanning each null space
        if heading is None:
            nvec = np.concatenate([nvec, -nvec])
            frontier = np.concatenate([frontier, frontier])
        else:
            nvec *= np.where((nvec * heading).sum(1) < 0, -1.0, 1.0)[:, None]
        start = np.clip(frontier + cfg.walk_step * nvec, ctx.robot.lower, ctx.robot.upper)
        r = refine(ctx, start, goal, deadline, cfg.walk_iterations)
        step = assess(r.q, _unindexed(r.q, c.z.shape[1]), r.perr, r.oerr, goal.kind, cfg)
        pick = np.empty(0, dtype=int)
        if step.exact.any():
            far_enough = cdist(step.q[step.exact], found).min(axis=1) >= cfg.distinct_threshold
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
