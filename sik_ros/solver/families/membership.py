"""Posture families: which of a goal's exact solutions are one way of reaching it.

A family is a connected set of a goal's exact solutions within the joint limits, periodic joints
taken modulo 2 pi:

- an arm with six joints or fewer at a pose has isolated solutions: a family is a *branch*,
  the solutions equal modulo 2 pi on periodic joints (the same placement of the arm), within
  :data:`~sik_ros.solver.config.SAME_BRANCH`; solutions of two branches are never merged as
  near postures (:func:`same_solution`);
- a redundant arm (and any arm at a position goal) has self-motion: a family is a connected
  piece of it within the limits. Two solutions are one family when a corrected straight
  segment links them, directly (up to ``FAMILY_REACH`` apart) or through others: a
  certificate of connection, so solutions it fails to link count as two families, as far as
  the solver knows. On the Panda these labels are those of tracing each one-dimensional
  self-motion curve from every solution (:func:`traced`, at 1.5x the time of a solve;
  docs/design.md).

The compiled tests are in :mod:`sik_ros.kernels.families`. Ranking takes the best of each
family first (:func:`rounds`); with the default ranking of a pose whose every family is
known, then a second of each, the one farthest from its first, and so on: the answers spread
over every family.
"""

import functools
import math
from typing import List, Sequence

import numpy as np

from sik_ros.deadline import Deadline
from sik_ros.kernels import as_arg
from sik_ros.kernels.families import (branch_labels, SEGMENT, segment_labels, spread_rounds,
                                      trace_labels)
from sik_ros.kernels.selfmotion import TRACE
from sik_ros.solver.batch import Candidates
from sik_ros.solver.config import (FAMILY_LINK, FAMILY_REACH, FAMILY_SEGMENT_STEP,
                                   FAMILY_TRACE_STEP, FAMILY_TRACE_STEPS, SAME_BRANCH)
from sik_ros.solver.context import Context, Goal, POSE
from sik_ros.solver.refine import NO_ROTATION
from sik_ros.solver.results import NO_FAMILY, Solution


def trace_settings(step: float, max_steps: int, link: float, cfg, deadline: Deadline
                   ) -> np.ndarray:
    """A trace's settings array (:data:`~sik_ros.kernels.selfmotion.TRACE`).

    Its step [rad], most steps each way, link distance [rad], ``cfg``'s tolerances and
    largest joint step, and ``deadline``.
    """
    settings = _settings(TRACE, cfg, step=step, max_steps=max_steps, link=link).copy()
    settings[TRACE.index('deadline')] = deadline.at
    return settings


def segment_settings(cfg, deadline: Deadline) -> np.ndarray:
    """:func:`segment_labels`' settings array (:data:`~sik_ros.kernels.families.SEGMENT`)."""
    settings = _settings(SEGMENT, cfg, step=FAMILY_SEGMENT_STEP, reach=FAMILY_REACH).copy()
    settings[SEGMENT.index('deadline')] = deadline.at
    return settings


@functools.lru_cache(maxsize=64)
def _settings(fields, cfg, **given) -> np.ndarray:
    """A kernel's settings array of ``fields``: ``given``, ``cfg``'s tolerances and step.

    Its deadline infinite; shared, made once each: a caller copies it.
    """
    values = dict(given, position_tolerance=cfg.position_tolerance,
                  orientation_tolerance=cfg.orientation_tolerance, max_step=cfg.max_step,
                  deadline=math.inf)
    return np.array([values[k] for k in fields], dtype=float)


def isolated(ctx: Context, kind: str) -> bool:
    """Whether a ``kind`` goal's solutions are isolated: a pose of an arm of 6 joints or fewer."""
    return kind == POSE and ctx.robot.dof <= 6


def same_solution(ctx: Context, kind: str) -> float:
    """Distance [rad] under which two exact solutions of a ``kind`` goal are merged as one.

    Isolated solutions: :data:`~sik_ros.solver.config.SAME_BRANCH` (or ``distinct_threshold``
    when smaller), so two branches are never merged by the distance; otherwise
    ``distinct_threshold``.
    """
    threshold = float(ctx.config.distinct_threshold)
    return min(SAME_BRANCH, threshold) if isolated(ctx, kind) else threshold


def labels(ctx: Context, q: np.ndarray, goal: Goal, deadline: Deadline) -> np.ndarray:
    """(M,) int64: each exact solution's family root (the smallest row of its family).

    ``q`` (M, n) [rad]: exact solutions of ``goal``. Past ``deadline`` solutions not yet
    linked stay families of their own.
    """
    cfg, robot = ctx.config, ctx.robot
    q = as_arg(q)
    if len(q) < 2:
        return np.arange(len(q))
    periodic = as_arg(robot.periodic, bool)
    pose = goal.kind == POSE
    if isolated(ctx, goal.kind):
        return branch_labels(q, same_solution(ctx, goal.kind), periodic)
    rot = as_arg(goal.rotation) if pose else NO_ROTATION
    args = (robot.frames, robot.lower, robot.upper, periodic, q, as_arg(goal.position), rot)
    return segment_labels(*args, pose, segment_settings(cfg, deadline))


def traced(ctx: Context, q: np.ndarray, goal: Goal, deadline: Deadline) -> np.ndarray:
    """(M,) int64: family roots of a 7-joint arm's exact pose solutions by tracing the curve.

    The reference the segment links are checked against (tests, docs/design.md): each
    solution's self-motion followed both ways in steps of ``FAMILY_TRACE_STEP``.
    """
    cfg, robot = ctx.config, ctx.robot
    if robot.dof != 7 or goal.kind != POSE:
        raise ValueError('tracing needs a pose goal of a 7-joint arm')
    return trace_labels(robot.frames, robot.lower, robot.upper,
                        as_arg(robot.periodic, bool), as_arg(q), as_arg(goal.position),
                        as_arg(goal.rotation),
                        trace_settings(FAMILY_TRACE_STEP, FAMILY_TRACE_STEPS,
                                       FAMILY_LINK * FAMILY_TRACE_STEP, cfg, deadline))


def roots(ctx: Context, c: Candidates, goal: Goal, deadline: Deadline,
          atlas=None) -> np.ndarray:
    """(M,) int64: the family root of each exact candidate of ``c`` (a row of ``c``), -1 else.

    With an ``atlas`` of the pose (:class:`~sik_ros.solver.families.search.Atlas`), a family is
    one of its pieces; rows on none of them (found after the search) and every row without an
    atlas are linked by :func:`labels`.
    """
    out = np.full(len(c), -1, dtype=np.int64)
    rows = np.flatnonzero(c.exact)
    if not len(rows):
        return out
    if atlas is None:
        out[rows] = rows[labels(ctx, c.q[rows], goal, deadline)]
        return out
    pieces = atlas.pieces_of(c.q[rows], ctx.robot.periodic)
    first = {}
    for row, piece in zip(rows.tolist(), pieces.tolist()):
        if piece >= 0:
            out[row] = first.setdefault(piece, row)
    off = rows[pieces < 0]  # found after the search (restarts for a free solution)
    if len(off):
        out[off] = off[labels(ctx, c.q[off], goal, deadline)]
    return out


def rounds(families: np.ndarray, order: np.ndarray, q: np.ndarray, periodic: np.ndarray,
           spread: bool = True) -> np.ndarray:
    """(M,) int64: each row's round in its family (0: its first in ``order``; none: 0).

    With ``spread`` a family's later rounds take, one at a time, its row farthest from those
    of the rounds before (:func:`~sik_ros.kernels.families.spread_rounds`); without, every
    later row is round 1 (a family's first, then the rest in ``order``). ``families`` (M,):
    family roots, -1 for none; ``order``: the rows, best first; ``q`` (M, n): the rows.
    """
    families = np.ascontiguousarray(families, dtype=np.int64)
    if not len(families):
        return np.zeros(0, dtype=np.int64)
    dense = families
    if families.max() >= len(families):  # roots are rows, as a rule; else numbered afresh
        _, dense = np.unique(families, return_inverse=True)
        dense = np.where(families >= 0, dense - (families.min() < 0), -1)
    return spread_rounds(as_arg(q), np.ascontiguousarray(dense, dtype=np.int64),
                         np.ascontiguousarray(order, dtype=np.int64), as_arg(periodic, bool),
                         bool(spread))


def number(sols: Sequence[Solution], families: Sequence[int]) -> int:
    """Number the solutions' families by first appearance (0: the best-ranked family).

    ``families``: every family root found (of the returned solutions and the others), each
    solution's own in its ``family`` field (-1 or :data:`NO_FAMILY`: none). Families found
    but not returned are counted, not numbered. Returns how many families were found.
    """
    values = families.tolist() if isinstance(families, np.ndarray) else families
    found = {int(f) for f in values if 0 <= int(f) < NO_FAMILY}
    named = {}
    for s in sols:
        if 0 <= s.family < NO_FAMILY and s.family in found:
            s.family = named.setdefault(s.family, len(named))
        else:
            s.family = NO_FAMILY
    return len(found)


def one_per_family(sols: List[Solution]) -> List[Solution]:
    """The best solution of each family (ranked order kept); those without one stay."""
    seen = set()
    out = []
    for s in sols:
        if s.family != NO_FAMILY:
            if s.family in seen:
                continue
            seen.add(s.family)
        out.append(s)
    return out
