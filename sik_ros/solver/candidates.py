"""Where refinement starts: posture indices from the table and the postures they stand for.

The table's indices in the cells near the goal, with the seed's own index first, thinned to a
far-apart subset (:func:`table_candidates`); their postures, from the table's decoded postures
when it keeps them, else decoded at the goal (:func:`starting_postures`); and for pose goals the
position model's postures whose tips had the goal's orientation, the last joint turned towards it
(:func:`oriented_postures`, :func:`align_last_joint`).
"""

import math
from typing import Optional, Tuple

import numpy as np

from sik_ros.kernels import as_arg
from sik_ros.kernels.chain import align_last_many
from sik_ros.solver.codec import branch_codes, decode, encode
from sik_ros.solver.context import Context, Goal, POSITION
from sik_ros.tables.point_sets import farthest_point_subset


def table_candidates(ctx: Context, goal: Goal, q_seed: Optional[np.ndarray],
                     num_solutions: int = 16, refine: bool = True,
                     others: int = 0) -> Tuple[np.ndarray, np.ndarray]:
    """Posture indices to decode, the seed's own index first, and the table row of each.

    Args:
        ctx: the solver's parts.
        goal: the target.
        q_seed: the current configuration (n,), or None.
        num_solutions: solutions asked for.
        refine: False for raw answers, which take a larger pool.
        others: candidates coming from elsewhere (oriented postures), which count towards the
            ``candidates_per_solution`` per solution asked for.

    Returns:
        indices (M, latent) and their table rows (M,) (-1: not from the table).
    """
    cfg = ctx.config
    count = max(cfg.num_candidates if goal.kind == POSITION else cfg.pose_candidates,
                math.ceil(cfg.candidates_per_solution * num_solutions) - others)
    if not refine:
        count = max(count, cfg.raw_candidates)
    table = ctx.models[goal.kind].table
    if count <= 0:  # none from the table: only the seed's own index (its posture kept)
        return own_index(ctx, goal, q_seed)
    mcfg = getattr(ctx.models[goal.kind].model, 'cfg', None)  # None: no learned model
    line = getattr(mcfg, 'latent_dim', table.indices.shape[1]) == 1
    if goal.kind != POSITION and not line and table.orientations is not None:
        # a pose model's index of more than one element holds the posture of a whole
        # position's self-motion: only those of rows whose tips had nearly the goal's
        # orientation stand for postures that reach it (the paper's look-up over positions
        # and orientations), the nearest first. As many cells as candidates wanted (at least
        # ``oriented_cells``): a raw call's 192 from 125 cells instead of 27 came 1.72 cm /
        # 31 deg from the goal instead of 1.98 cm / 44 deg (Panda, 60 targets)
        rows = table.oriented_rows(goal.position, goal.quaternion, count,
                                   max(cfg.oriented_cells, count))
    else:
        # a table that marks the indices its decoder realises holds fewer of them per cell:
        # as many from more cells
        rows = table.rows_near(goal.position, table.pool_cells(cfg.k_cells))
    pool = table.indices[rows]
    if line:
        # a 1-d index is a line (one per branch code): also sweep it over the range the table
        # holds, on every branch
        sweep = index_sweep(table, getattr(mcfg, 'branches', ()), count)
        pool = np.concatenate([pool, sweep])
        rows = np.concatenate([rows, np.full(len(sweep), -1)])
    if q_seed is not None:
        z_seed = encode(ctx, goal, q_seed[None])[0]
        pool = np.concatenate([z_seed[None], pool])
        rows = np.concatenate([[-1], rows])
    pick = farthest_point_subset(pool, count)
    return pool[pick], rows[pick]


def index_sweep(table, branches, count: int) -> np.ndarray:
    """About ``count`` indices (M, 1 + bits) along a 1-d index's range, on every branch code."""
    codes = branch_codes(branches)
    lo, hi = table.index_bounds
    line = np.linspace(lo[:1], hi[:1], max(2, math.ceil(count / len(codes))))
    return np.concatenate([np.concatenate([line, np.repeat(c[None], len(line), 0)], axis=1)
                           for c in codes])


def own_index(ctx: Context, goal: Goal, q_seed: Optional[np.ndarray]
              ) -> Tuple[np.ndarray, np.ndarray]:
    """The seed's own posture index (1, latent) and row -1 (none without a seed)."""
    if q_seed is None:
        latent = ctx.models[goal.kind].table.indices.shape[1]
        return np.empty((0, latent)), np.empty(0, dtype=int)
    return encode(ctx, goal, q_seed[None]), np.array([-1])


def starting_postures(ctx: Context, goal: Goal, z: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Postures (M, n) to refine from, for indices ``z`` from table ``rows`` (-1: none).

    Table rows take the table's decoded postures (when it keeps them and
    ``config.cached_postures``); the others are decoded at the goal.
    """
    postures = ctx.models[goal.kind].table.postures
    if postures is None or not ctx.config.cached_postures:
        return decode(ctx, goal, z)
    cached = rows >= 0
    q = np.empty((len(z), ctx.robot.dof))
    # float32 storage: clip back onto the limits
    q[cached] = np.clip(postures[rows[cached]], ctx.robot.lower, ctx.robot.upper)
    if not cached.all():
        q[~cached] = decode(ctx, goal, z[~cached])
    return q


def oriented_postures(ctx: Context, goal: Goal, count: int) -> np.ndarray:
    """Postures (M, n) for a pose goal from the position model's orientation-aware table.

    The position model's indices whose dataset rows had tip orientations nearest the goal
    keep those postures when decoded near the goal position (the table's decoded posture at
    the cell centre, or a decode at the goal); the last joint, free for a position goal, is
    then set in closed form to bring the tip orientation closest to the goal. Empty when the
    bundle has no position model or its table keeps no orientations.
    """
    gm = ctx.models.get(POSITION)
    if gm is None or gm.table.orientations is None or count < 1:
        return np.empty((0, ctx.robot.dof))
    rows = gm.table.oriented_rows(goal.position, goal.quaternion, count,
                                  ctx.config.oriented_cells)
    q = starting_postures(ctx, Goal(goal.position), gm.table.indices[rows], rows)
    return align_last_joint(ctx, q, goal.rotation)


def align_last_joint(ctx: Context, q: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """``q`` with the last joint turned (within its limits) towards the orientation ``rot``.

    Every joint turns about its own z axis, so the best angle has a closed form
    (:func:`~sik_ros.kernels.chain.align_last_many`).
    """
    q = as_arg(q).copy()
    robot = ctx.robot
    align_last_many(robot.frames, q, as_arg(rot), float(robot.lower[-1]), float(robot.upper[-1]))
    return q
