"""The family search: every piece of a redundant arm's self-motion at a pose, as a sweep finds.

A 7-joint arm reaches a pose along one-dimensional self-motion curves; the joint limits cut
them into the pose's posture families. The table's postures and refinement find solutions on
the families near where they start; an analytic solver sweeping one joint finds every piece.
:func:`search` does what the sweep does from the solutions found: each one's curve is
followed *past* the limits until it closes (:func:`sik_ros.kernels.selfmotion.trace_atlas`),
so pieces that the limits part from it are reached; curves through none of them are reached
from a sweep of the last joint (:func:`swept`) and through the arm's exact flips
(:func:`sik_ros.kinematics.branches.exact_flips`: a spherical shoulder turned over), where
it has them. The traced points within the limits are the pose's
:class:`Atlas`: its pieces are the families (the labels of :mod:`sik_ros.solver.families`),
and points far apart on each join the candidates, so a call gets its distinct solutions from
every family without walking (:func:`sik_ros.solver.explore.walk`). Its points are exact (the
tracer's corrector meets the tolerances).
"""

from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np

from sik_ros.deadline import Deadline
from sik_ros.kernels import as_arg
from sik_ros.kernels.selfmotion import atlas_pieces, spread_points, trace_atlas
from sik_ros.kernels.sets import farthest_rows
from sik_ros.kinematics.branches import robot_flips
from sik_ros.solver.batch import Candidates
from sik_ros.solver.config import (SEARCH_LINK, SEARCH_PER_PIECE, SEARCH_POINTS,
                                   SEARCH_RECORDED, SEARCH_STEP, SEARCH_STEPS, SEARCH_SWEEP,
                                   START_MERGE, SWEEP_ITERATIONS, SWEEP_STARTS)
from sik_ros.solver.context import Context, Goal, POSE
from sik_ros.solver.explore import unindexed
from sik_ros.solver.ranking import assess, converged, distinct_mask
from sik_ros.solver.refine import errors, refine


@dataclass(frozen=True)
class Atlas:
    """The traced self-motion of one pose: points within the limits and their pieces.

    Attributes:
        points: recorded points (P, 7) [rad], exact solutions of the pose.
        pieces: each point's piece (P,): points of one piece are one posture family.
        link: a solution this close to a point [rad] lies on its piece.
    """

    points: np.ndarray
    pieces: np.ndarray
    link: float

    def pieces_of(self, q: np.ndarray, periodic: np.ndarray) -> np.ndarray:
        """(M,) int64: the piece of each row of ``q`` (M, 7), -1 for rows on none."""
        return atlas_pieces(self.points, self.pieces, len(self.points), as_arg(q),
                            as_arg(periodic, bool), self.link)


def swept(ctx: Context, c: Candidates, goal: Goal, deadline: Deadline) -> np.ndarray:
    """Exact solutions with the last joint held at values across its range.

    As an analytic solver sweeping it finds them: at each of :data:`SEARCH_SWEEP` values,
    evenly inside the range, the candidates' configurations (the table's postures, refined
    or not, those alike but for the held joint once, at most :data:`SWEEP_STARTS` of them
    farthest apart) with that value, refined with the joint held. They land on curves of the
    self-motion the candidates' own refinement may not reach (docs/design.md).
    """
    robot = ctx.robot
    j = robot.dof - 1
    # configurations alike but for the held joint refine alike
    starts = c.q[distinct_mask(np.delete(c.q, j, axis=1),
                               ctx.config.distinct_threshold * START_MERGE)]
    if len(starts) > SWEEP_STARTS:
        starts = starts[farthest_rows(as_arg(np.delete(starts, j, axis=1)), SWEEP_STARTS, 0,
                                      0.0, 0, 0.0)]
    out = []
    for v in np.linspace(robot.lower[j], robot.upper[j], SEARCH_SWEEP + 2)[1:-1]:
        lower, upper = robot.lower.copy(), robot.upper.copy()
        lower[j] = upper[j] = v
        q = starts.copy()
        q[:, j] = v
        r = refine(ctx, q, goal, deadline, SWEEP_ITERATIONS, prune=True, limits=(lower, upper))
        out.append(r.q[converged(r.perr, r.oerr, goal.kind, ctx.config)])
    return np.concatenate(out) if out else np.empty((0, robot.dof))


def searchable(ctx: Context, goal: Goal) -> bool:
    """Whether the search applies: a pose goal of a 7-joint arm (a one-dimensional self-motion)."""
    return goal.kind == POSE and ctx.robot.dof == 7 and ctx.config.family_search


def search(ctx: Context, c: Candidates, goal: Goal,
           deadline: Deadline) -> Tuple[Candidates, Optional[Atlas]]:
    """``c`` and points far apart on every piece of the curves its exact solutions lie on.

    Only before ``deadline``; nothing is added without an exact solution to start from.

    Returns:
        the candidates, and the pose's :class:`Atlas` (None when nothing was traced).
    """
    if not c.exact.any() or deadline.expired():
        return c, None
    cfg, robot = ctx.config, ctx.robot
    periodic = as_arg(robot.periodic, bool)
    held = swept(ctx, c, goal, deadline)
    known = as_arg(np.concatenate([c.q[c.exact], held]))
    points = np.empty((SEARCH_RECORDED, robot.dof))
    piece = np.empty(SEARCH_RECORDED, dtype=np.int64)
    row_piece = np.empty(len(known), dtype=np.int64)
    count = trace_atlas(robot.frames, robot.lower, robot.upper, periodic, known,
                        robot_flips(robot), as_arg(goal.position), as_arg(goal.rotation),
                        SEARCH_STEP, SEARCH_STEPS, SEARCH_LINK, cfg.position_tolerance,
                        cfg.orientation_tolerance, cfg.max_step, deadline.at, points, piece,
                        row_piece)
    if count == 0:
        return c, None
    out = np.empty((SEARCH_POINTS, robot.dof))
    out_piece = np.empty(SEARCH_POINTS, dtype=np.int64)
    k = spread_points(points, piece, count, known, row_piece, periodic,
                      float(cfg.distinct_threshold), SEARCH_PER_PIECE, out, out_piece)
    atlas = Atlas(points[:count].copy(), piece[:count].copy(), SEARCH_LINK)
    if k == 0:
        return c, atlas
    q = out[:k].copy()
    perr, oerr = errors(ctx, q, goal)
    more = assess(q, unindexed(q, c.z.shape[1]), perr, oerr, goal.kind, cfg)
    return Candidates.concat(c, more), atlas
