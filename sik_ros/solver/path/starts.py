"""Where tracks start: the seed, the table's postures near it, or the solver's solutions."""

from typing import Optional, Tuple

import numpy as np

from sik_ros.deadline import Deadline, NO_DEADLINE
from sik_ros.kinematics.periodic import nearest_turns
from sik_ros.solver import pipeline  # noqa: I100 (a sibling module, not the package)
from sik_ros.solver.config import NEAR_POOL, START_ITERATIONS
from sik_ros.solver.context import Context, Goal, POSITION
from sik_ros.solver.refine import Evaluation, follow
from sik_ros.solver.scores import distinct_mask


def track_starts(ctx: Context, goal: Goal, q_seed, obstacles, count: int,
                 deadline: Deadline = NO_DEADLINE,
                 near_seed: bool = True) -> Tuple[np.ndarray, Evaluation]:
    """Distinct exact configurations at a waypoint, free of collisions, and their evaluations.

    A path should start near the current state (the seed). At a pose waypoint with a seed the
    solver refines every candidate to its end (the seed's own row among them) for the
    solutions nearest the seed. At a position waypoint with a seed the seed itself and the
    table's postures nearest it (:func:`table_near_seed`) are followed onto the waypoint together
    (:func:`followed`): no decoding or ranking, the rows already near the goal and the
    seed. Without ``near_seed`` (or postures in the table, or with ``cached_postures`` off),
    for starts spread over the postures (a wider beam's second try), the seed followed and
    the solver's first distinct exact solutions. Without a seed (new starts where every track
    was lost) the solver's first distinct exact solutions, as for any goal. Why these starts:
    docs/design.md.
    """
    if goal.rotation is not None or q_seed is None:
        return solver_starts(ctx, goal, q_seed, obstacles, count, deadline, False)
    near = table_near_seed(ctx, goal, q_seed, count) if near_seed else None
    rows = q_seed[None] if near is None else np.concatenate([q_seed[None], near])
    parts = [followed(ctx, rows, goal, obstacles, deadline)]
    if near is None:
        parts.append(solver_starts(ctx, goal, q_seed, obstacles, count, deadline, True))
    q, ev = distinct_union(ctx, *parts)
    if len(q) < min(2, count) and not deadline.expired():
        # few of them reached the waypoint free of collisions: all the solver's then, as at a
        # pose waypoint
        q, ev = distinct_union(ctx, (q, ev), solver_starts(ctx, goal, q_seed, obstacles,
                                                           count, deadline, False))
    return q, ev


def table_near_seed(ctx: Context, goal: Goal, q_seed: np.ndarray, count: int
                    ) -> Optional[np.ndarray]:
    """Up to ``count - 1`` of the table's postures near a position goal, nearest the seed.

    The postures decoded at the cells nearest the goal (the table's cached ones) are a few
    refinement steps from it. Periodic joints take the 2 pi turn nearest the seed, and a last
    joint that only turns the tool about its axis (:meth:`Context.ignores_last`) the seed's
    own value (refinement leaves it where it is). Of the :data:`NEAR_POOL` nearest the seed
    (L2 over the joints), greedily those distinct from the seed and from each other. None
    when the table keeps no postures or ``config.cached_postures`` is off.
    """
    table = ctx.models[POSITION].table
    if table.postures is None or not ctx.config.cached_postures:
        return None
    rows = table.rows_near(goal.position, table.pool_cells(ctx.config.k_cells))
    q = np.clip(table.postures[rows].astype(np.float64), ctx.robot.lower, ctx.robot.upper)
    q = nearest_turns(ctx.robot, q, q_seed)
    if ctx.ignores_last(POSITION):
        q[:, -1] = q_seed[-1]
    q = q[np.argsort(np.linalg.norm(q - q_seed, axis=1), kind='stable')[:NEAR_POOL]]
    q = np.concatenate([q_seed[None], q])
    keep = distinct_mask(q, ctx.config.distinct_threshold, ctx.ignores_last(POSITION))
    return q[1:][keep[1:]][:count - 1]


def followed(ctx: Context, q: np.ndarray, goal: Goal, obstacles,
             deadline: Deadline) -> Tuple[np.ndarray, Evaluation]:
    """The rows of ``q`` that :func:`follow` takes onto ``goal`` free of collisions.

    They start tracks: no change of their Jacobian from a previous waypoint (the one from the
    current state or a table posture is no waypoint step).
    """
    _, q, ev = follow(ctx, q, Evaluation.of(ctx, q), goal,
                      min(START_ITERATIONS, ctx.config.refine_iterations), deadline)
    free = ~ctx.checker.self_collision(q)
    if obstacles and free.any():
        free[free] = ctx.checker.clearance(q[free], obstacles, deadline) > 0
    ev = ev.rows(free)
    return q[free], Evaluation(ev.p, ev.r, ev.jac, np.zeros_like(ev.jac))


def distinct_union(ctx: Context, *parts: Tuple[np.ndarray, Evaluation]
                   ) -> Tuple[np.ndarray, Evaluation]:
    """The rows of several position-waypoint starts, in order, one per distinct posture."""
    q = np.concatenate([part[0] for part in parts])
    ev = Evaluation.concat(*(part[1] for part in parts))
    keep = distinct_mask(q, ctx.config.distinct_threshold, ctx.ignores_last(POSITION))
    return q[keep], ev.rows(keep)


def solver_starts(ctx: Context, goal: Goal, q_seed, obstacles, count: int, deadline: Deadline,
                  first_found: bool) -> Tuple[np.ndarray, Evaluation]:
    """The solver's exact solutions free of collisions at a waypoint, and their evaluations."""
    res = pipeline.solve(ctx, goal, count, q_seed, obstacles, True, None, deadline,
                         first_found=first_found)
    q = np.array([s.q for s in res.solutions if s.converged and not s.in_collision])
    q = q.reshape(-1, ctx.robot.dof)
    return q, Evaluation.of(ctx, q)
