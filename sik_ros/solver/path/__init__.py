"""Cartesian paths: joint paths through a sequence of tool poses, without flips.

At the first waypoint (and wherever every track is lost) distinct exact configurations start
*tracks*: the solver's solutions (with the seed's own posture and the 2 pi equivalents of
periodic joints), or at a position waypoint the seed and the table's postures nearest it
followed onto the waypoint (:func:`track_starts`); at each
next waypoint every track is continued by refining its last configuration onto the new pose (a
warm start: the posture is kept, the paper's "keep the posture" strategy). The candidates of
consecutive waypoints form a ladder graph; an edge is allowed when no joint moves more than
``max_joint_step`` and the tool stays on the Cartesian segment between the two waypoints
(checked by FK of interpolated configurations, only for the edges that would be chosen and
that a curvature bound does not already prove on the segment), and is
weighted by its joint travel (plus the distance of the start from the seed). Dynamic
programming over the ladder (a beam of the ``tracks`` cheapest candidates per waypoint) gives
the cheapest paths; the best few, from distinct starts, are returned. When no candidate of a
waypoint can be reached, the longest feasible prefix is returned with its ``fraction``, as MoveIt's
``computeCartesianPath`` does.

The whole ladder (tracks switching, merging, refilled by new starts) joins every
``ladder``-th waypoint (:class:`PathSettings`) to the one before; between two of them every
track continues itself, and those waypoints are solved in one batch (:func:`chunk`): the
tracks' steps predicted from their Jacobians, then refined and checked all at once. The
first such batch starts from the starts themselves. A batch that would leave fewer than two
tracks at a waypoint (none, when it began with one) is dropped, and those waypoints go on one
at a time. The paths' errors come from the tip poses computed when their configurations were
refined.
"""

from sik_ros.solver.path.ladder import solve_path
from sik_ros.solver.path.settings import (JointPath, PathResult, PathSettings, POSE_BEAM,
                                          POSITION_BEAM)

__all__ = ['JointPath', 'PathResult', 'PathSettings', 'POSE_BEAM', 'POSITION_BEAM',
           'solve_path']
