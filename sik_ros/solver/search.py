"""The family search: every piece of a redundant arm's self-motion at a pose, as a sweep finds.

A 7-joint arm reaches a pose along one-dimensional self-motion curves; the joint limits cut
them into the pose's posture families. The table's postures, refinement and the walk
(:func:`sik_ros.solver.explore.walk`) find solutions on the families near where they start;
an analytic solver sweeping one joint finds every piece. :func:`search` does what the sweep
does from the solutions found: each one's curve is followed *past* the limits
(:func:`sik_ros.kernels.sweep.trace_pieces`), so pieces that the limits part from it are
reached, and a point of every piece within the limits that holds no found solution joins the
candidates. Curves through none of them are reached through the arm's exact flips
(:func:`sik_ros.kinematics.branches.exact_flips`: a spherical shoulder turned over), where it
has them. Its points are exact (the tracer's corrector meets the tolerances), and the family
labels then link or part them as any other (:mod:`sik_ros.solver.families`).
"""

import numpy as np

from sik_ros.deadline import Deadline
from sik_ros.kernels import as_arg
from sik_ros.kernels.sweep import trace_pieces
from sik_ros.kinematics.branches import robot_flips
from sik_ros.solver.batch import Candidates
from sik_ros.solver.config import (SEARCH_LINK, SEARCH_POINTS, SEARCH_STEP, SEARCH_STEPS)
from sik_ros.solver.context import Context, Goal, POSE
from sik_ros.solver.explore import unindexed
from sik_ros.solver.ranking import assess
from sik_ros.solver.refine import errors


def searchable(ctx: Context, goal: Goal) -> bool:
    """Whether the search applies: a pose goal of a 7-joint arm (a one-dimensional self-motion)."""
    return goal.kind == POSE and ctx.robot.dof == 7 and ctx.config.family_search


def search(ctx: Context, c: Candidates, goal: Goal, deadline: Deadline) -> Candidates:
    """``c`` and a point of every piece of the self-motion its exact solutions' curves cross.

    Only before ``deadline``; nothing is added without an exact solution to start from.
    """
    if not c.exact.any() or deadline.expired():
        return c
    cfg, robot = ctx.config, ctx.robot
    out = np.empty((SEARCH_POINTS, robot.dof))
    owner = np.empty(SEARCH_POINTS, dtype=np.int64)
    count = trace_pieces(robot.frames, robot.lower, robot.upper, as_arg(c.q[c.exact]),
                         robot_flips(robot), as_arg(goal.position), as_arg(goal.rotation),
                         SEARCH_STEP, SEARCH_STEPS, SEARCH_LINK, cfg.position_tolerance,
                         cfg.orientation_tolerance, cfg.max_step, out, owner)
    if count == 0:
        return c
    q = out[:count].copy()
    perr, oerr = errors(ctx, q, goal)
    return Candidates.concat(c, assess(q, unindexed(q, c.z.shape[1]), perr, oerr, goal.kind,
                                       cfg))
