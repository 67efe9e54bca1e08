"""The family search: every piece of a redundant arm's self-motion at a pose, as a sweep finds.

A 7-joint arm reaches a pose along one-dimensional self-motion curves; the joint limits cut
them into the pose's posture families. The table's postures and refinement find solutions on
the families near where they start; an analytic solver sweeping one joint finds every piece.
:func:`search` does what the sweep does from the solutions found: each one's curve is
followed *past* the limits until it closes (:func:`sik_ros.kernels.atlas.trace_atlas`),
so pieces that the limits part from it are reached; curves through none of them are reached
through the arm's exact flips (:func:`sik_ros.kinematics.branches.exact_flips`: a spherical
shoulder turned over), where it has them, and from the solutions mirrored across the singular
angles of the arm with its last joint held (:func:`mirrored`: at one value of that joint, the
other branches an analytic solver sweeping it finds, such as the elbow's other side). The
traced points within the limits are the pose's :class:`Atlas`: its pieces are the families
(the labels of :mod:`sik_ros.solver.families.membership`), and points far apart on each join the
candidates, so a call gets its distinct solutions from every family without walking
(:func:`sik_ros.solver.explore.walk`). Its points are exact (the tracer's corrector meets the
tolerances).
"""

from dataclasses import dataclass
import functools
from typing import List, Optional, Tuple

import numpy as np

from sik_ros.deadline import Deadline
from sik_ros.kernels import as_arg
from sik_ros.kernels.angles import turned_rows
from sik_ros.kernels.atlas import trace_atlas
from sik_ros.kernels.atlas_points import atlas_pieces, spread_points
from sik_ros.kinematics.branches import robot_flips, singular_angles
from sik_ros.kinematics.robot import Robot
from sik_ros.solver.batch import Candidates
from sik_ros.solver.config import (MIRROR_ITERATIONS, SEARCH_LINK, SEARCH_PER_PIECE,
                                   SEARCH_POINTS, SEARCH_RECORDED, SEARCH_STEP, SEARCH_STEPS,
                                   START_MERGE)
from sik_ros.solver.context import Context, Goal, POSE
from sik_ros.solver.explore import unindexed
from sik_ros.solver.families.branches import fits_mirrored
from sik_ros.solver.families.membership import trace_settings
from sik_ros.solver.refine import errors, refine
from sik_ros.solver.scores import assess, converged, distinct_mask


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


@functools.lru_cache(maxsize=16)
def robot_mirrors(robot: Robot) -> Tuple[np.ndarray, np.ndarray]:
    """The joints (int64) and angles [rad] the search mirrors solutions about, once per arm.

    The singular angles of the arm with its last joint held
    (:func:`~sik_ros.kinematics.branches.singular_angles`) whose mirror can fit the joint's
    limits (:func:`~sik_ros.solver.families.branches.fits_mirrored`), one of two half a turn apart
    (the same mirror), less the middle joint of an exact flip: mirrored, it gives the flip's
    curve, recorded as a twin.
    """
    flips = robot_flips(robot)
    pairs: List[Tuple[int, float]] = []
    for j, c in singular_angles(robot, robot.dof - 1):
        if j in flips + 1 or not fits_mirrored(robot, j, c):
            continue
        if not any(k == j and abs(np.sin(c - b)) < 1e-6 for k, b in pairs):
            pairs.append((j, c))
    return (np.array([j for j, _ in pairs], dtype=np.int64),
            np.array([c for _, c in pairs], dtype=float))


def mirrored(ctx: Context, q: np.ndarray, goal: Goal, deadline: Deadline) -> np.ndarray:
    """Exact solutions across the held arm's singular angles from solutions ``q`` (M, 7).

    With its last joint held, a 7-joint arm's solutions are a 6-joint arm's branches, which
    singular angles part (:func:`robot_mirrors`: the Panda's elbow stretched and its wrist);
    a curve of the self-motion on the branch across one from a found solution is one no start
    of the table's may reach. Each solution with the joint mirrored about the angle (turned
    into the limits; rows that do not fit dropped; those within ``distinct_threshold`` times
    :data:`START_MERGE` of a solution of ``q`` or of an earlier one once) is a start there,
    refined with every joint free (:data:`MIRROR_ITERATIONS` at most).
    """
    robot = ctx.robot
    joints, centres = robot_mirrors(robot)
    if not len(q) or not len(joints):
        return np.empty((0, robot.dof))
    starts = []
    for j, c in zip(joints, centres):
        m = q.copy()
        m[:, j] = 2 * c - m[:, j]
        starts.append(m[turned_rows(m, robot.lower, robot.upper, m)])
    m = np.concatenate([q] + starts)
    m = m[len(q):][distinct_mask(m, ctx.config.distinct_threshold * START_MERGE)[len(q):]]
    r = refine(ctx, m, goal, deadline, MIRROR_ITERATIONS, prune=True)
    return r.q[converged(r.perr, r.oerr, goal.kind, ctx.config)]


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
    found = c.q[c.exact]
    known = as_arg(np.concatenate([found, mirrored(ctx, found, goal, deadline)]))
    points = np.empty((SEARCH_RECORDED, robot.dof))
    piece = np.empty(SEARCH_RECORDED, dtype=np.int64)
    row_piece = np.empty(len(known), dtype=np.int64)
    settings = trace_settings(SEARCH_STEP, SEARCH_STEPS, SEARCH_LINK, cfg, deadline)
    count = trace_atlas(robot.frames, robot.lower, robot.upper, periodic, known,
                        robot_flips(robot), as_arg(goal.position), as_arg(goal.rotation),
                        settings, points, piece, row_piece)
    if count == 0:
        return c, None
    out = np.empty((SEARCH_POINTS, robot.dof))
    out_piece = np.empty(SEARCH_POINTS, dtype=np.int64)
    n = len(found)  # the candidates': a piece only a mirrored start reached gets its middle
    k = spread_points(points, piece, count, known[:n], row_piece[:n], periodic,
                      float(cfg.distinct_threshold), SEARCH_PER_PIECE, out, out_piece)
    atlas = Atlas(points[:count].copy(), piece[:count].copy(), SEARCH_LINK)
    if k == 0:
        return c, atlas
    q = out[:k].copy()
    perr, oerr = errors(ctx, q, goal)
    more = assess(q, unindexed(q, c.z.shape[1]), perr, oerr, goal.kind, cfg)
    return Candidates.concat(c, more), atlas
