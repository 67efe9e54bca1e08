"""Compiled posture families: which exact solutions of one goal are connected.

A *family* is a connected set of a goal's exact solutions within the joint limits, periodic
joints taken modulo 2 pi (:mod:`sik_ros.solver.families.membership` says which test each arm
and goal gets):

- :func:`branch_labels`: isolated solutions (a pose goal of an arm with six joints or fewer):
  rows within ``threshold`` of each other, periodic joints at their nearest turn, are one
  branch;
- :func:`trace_labels`: the one-dimensional self-motion of a 7-joint arm at a pose: each curve
  is followed from an unlabelled solution both ways (predictor along the null space of the
  Jacobian, damped least squares corrector back onto the goal) until it leaves the limits,
  closes on itself or fails; every solution it passes belongs to the start's family;
- :func:`segment_labels`: self-motion of more dimensions (position goals, pose goals of 8+
  joints): two solutions are linked when the straight joint segment between them, each point
  corrected onto the goal, stays continuous and within the limits (nearest pairs first, only
  between families not yet linked).

Labels are each row's family root: the smallest row index of its family.
"""

import math

from numba import njit
import numpy as np

from sik_ros.kernels._cache import CACHE
from sik_ros.kernels.angles import angle_distance, PER_TURN, TURN, turn_once
from sik_ros.kernels.clock import monotonic
from sik_ros.kernels.selfmotion import (advance, correct, T_DEADLINE, T_LINK, T_MAX_STEP,
                                        T_MAX_STEPS, T_STEP, T_TOL_O, T_TOL_P)
from sik_ros.kernels.sets import root, roots, union

#: The fields of :func:`segment_labels`'s ``settings``, in order: the segment's step [rad],
#: the farthest pair tried [rad], the corrector's tolerances [m], [rad] and largest joint step
#: [rad], the deadline (a :func:`~sik_ros.kernels.clock.monotonic` time, inf for none).
SEGMENT = ('step', 'reach', 'position_tolerance', 'orientation_tolerance', 'max_step',
           'deadline')
S_STEP, S_REACH, S_TOL_P, S_TOL_O, S_MAX_STEP, S_DEADLINE = range(len(SEGMENT))


@njit('int64[::1](float64[:, ::1], int64[::1], int64[::1], boolean[::1], boolean)',
      cache=CACHE, nogil=True)
def spread_rounds(q, families, order, periodic, spread):  # pragma: no cover (compiled)
    """(M,) int64: each row's round in its family, the rows of each spread over it.

    Round 0: the first row of each family in ``order``; with ``spread``, each later round of
    a family the row of it farthest from those of earlier rounds (of two as far, the one
    earlier in ``order``); without, every later row round 1. ``families`` (M,): 0 .. M - 1,
    -1 for none (round 0).
    """
    m = q.shape[0]
    rounds = np.zeros(m, dtype=np.int64)
    count = np.zeros(m, dtype=np.int64)  # rows given a round, per family
    first = np.zeros(m, dtype=np.bool_)
    left = 0
    for i in order:
        f = families[i]
        if f < 0:
            continue
        if count[f] > 0:
            rounds[i] = 1
            left += 1
        else:
            count[f] = 1
            first[i] = True
    if not spread or left == 0:
        return rounds
    near = np.full(m, -1.0)  # to the rows of its family given a round (-1: given one)
    for i in range(m):
        f = families[i]
        if f < 0 or first[i]:
            continue
        near[i] = np.inf
        for j in range(m):
            if first[j] and families[j] == f:
                near[i] = angle_distance(q[i], q[j], periodic)
                break
    for _ in range(left):
        best, far = -1, -0.5
        for i in order:
            if near[i] > far:
                best, far = i, near[i]
        f = families[best]
        rounds[best] = count[f]
        count[f] += 1
        near[best] = -1.0
        for j in range(m):
            if families[j] == f and near[j] >= 0.0:
                near[j] = min(near[j], angle_distance(q[j], q[best], periodic))
    return rounds


@njit('int64[::1](float64[:, ::1], float64, boolean[::1])', cache=CACHE, nogil=True)
def branch_labels(q, threshold, periodic):  # pragma: no cover (compiled)
    """Each row's branch: the first earlier row within ``threshold`` [rad], else itself."""
    m = q.shape[0]
    labels = np.arange(m)
    for i in range(m):
        for j in range(i):
            if labels[j] == j and angle_distance(q[i], q[j], periodic) < threshold:
                labels[i] = j
                break
    return labels


@njit(cache=CACHE, nogil=True)
def _into_limits(x, lower, upper, periodic):  # pragma: no cover (compiled)
    """``x`` kept within the limits in place: periodic joints turned once, the others clamped."""
    for c in range(x.shape[0]):
        v = turn_once(x[c], lower[c], upper[c]) if periodic[c] else x[c]
        x[c] = min(max(v, lower[c]), upper[c])


@njit(cache=CACHE, nogil=True)
def _at_limit(x, lower, upper, periodic):  # pragma: no cover (compiled)
    """Whether a joint that does not wrap stands at (or beyond) a limit."""
    for j in range(x.shape[0]):
        if not periodic[j] and (x[j] <= lower[j] + 1e-9 or x[j] >= upper[j] - 1e-9):
            return True
    return False


@njit('int64[::1](float64[:, :, ::1], float64[::1], float64[::1], boolean[::1], '
      'float64[:, ::1], float64[::1], float64[:, ::1], float64[::1])', cache=CACHE, nogil=True)
def trace_labels(frames, lower, upper, periodic, q, pos, rot,
                 settings):  # pragma: no cover (compiled)
    """Family roots of exact pose solutions ``q`` (M, 7) of a 7-joint arm by tracing.

    ``settings``: float64 values named by :data:`~sik_ros.kernels.selfmotion.TRACE` (below by
    their names).

    From each solution not yet reached by an earlier trace, the self-motion curve is followed
    both ways in steps of ``step`` [rad] (at most ``max_steps`` per way): the unit null vector
    (kept pointing the way the trace goes), then the corrector onto the goal pose
    (tolerances ``tol_p`` [m], ``tol_o`` [rad]). A way ends where a joint that does not wrap
    reaches a limit (the family ends there), where the corrector fails or jumps more than two
    steps (a singularity), or where the curve closes on its start. Every solution within
    ``link`` [rad] of a point of the trace joins the start's family. Past ``deadline`` (a
    :func:`~sik_ros.kernels.clock.monotonic` time) no trace starts and a running one stops:
    solutions not reached stay families of their own.
    """
    step, max_steps, link = settings[T_STEP], int(settings[T_MAX_STEPS]), settings[T_LINK]
    tols = (settings[T_TOL_P], settings[T_TOL_O], settings[T_MAX_STEP])
    deadline = settings[T_DEADLINE]
    m, n = q.shape[0], q.shape[1]
    parent = np.arange(m)
    p, r = np.empty(3), np.empty((3, 3))
    jac, jm = np.empty((6, n)), np.empty((6, n))
    a, err, xs = np.empty((6, 6)), np.empty(6), np.empty(6)
    minor = np.empty((6, 6))
    chain, goal = (frames, lower, upper, periodic), (pos, rot, True)
    work = (p, r, jac, jm, a, err, xs)
    v, heading = np.empty(n), np.empty(n)
    x, prev = np.empty(n), np.empty(n)
    timed = deadline < np.inf
    for i in range(m):
        if root(parent, i) != i:  # reached by an earlier solution's trace
            continue
        closed = False
        for way in (1.0, -1.0):
            if closed:
                break
            x[:] = q[i]
            for s in range(max_steps):
                if timed and monotonic() > deadline:
                    return roots(parent)
                prev[:] = x
                if not advance(frames, x, heading, s == 0, way, step, p, r, jac, minor, v,
                               s > 0):
                    break
                _into_limits(x, lower, upper, periodic)
                if not correct(chain, x, goal, tols, work):
                    break
                if angle_distance(x, prev, periodic) > 2.0 * step:
                    break
                for k in range(m):
                    if k != i and angle_distance(x, q[k], periodic) < link:
                        union(parent, i, k)
                if s >= 2 and angle_distance(x, q[i], periodic) < link:
                    closed = True
                    break
                if _at_limit(x, lower, upper, periodic):
                    break
    return roots(parent)


@njit('int64[::1](float64[:, :, ::1], float64[::1], float64[::1], boolean[::1], '
      'float64[:, ::1], float64[::1], float64[:, ::1], boolean, float64[::1])', cache=CACHE,
      nogil=True)
def segment_labels(frames, lower, upper, periodic, q, pos, rot, pose,
                   settings):  # pragma: no cover (compiled)
    """Family roots of exact solutions ``q`` (M, n) linked by corrected straight segments.

    ``settings``: float64 values named by :data:`SEGMENT` (below by their names).

    Pairs up to ``reach`` [rad] apart are tried nearest first, only between families not yet
    joined (a chain of near solutions links far ones): the segment from
    one to the other (periodic joints the short way round) in points ``step`` [rad] apart,
    each point the previous corrected one moved by the segment's step and corrected onto
    the goal (``pose``: position and orientation, else position). The pair is linked when
    every point is corrected within the tolerances, stays within the limits and moves at
    most two steps, and the last lands within ``2 * step`` of the other solution. Past
    ``deadline`` no more pairs are tried.
    """
    step, reach = settings[S_STEP], settings[S_REACH]
    tols = (settings[S_TOL_P], settings[S_TOL_O], settings[S_MAX_STEP])
    deadline = settings[S_DEADLINE]
    m, n = q.shape[0], q.shape[1]
    parent = np.arange(m)
    if m < 2:
        return roots(parent)
    pairs = m * (m - 1) // 2
    dist = np.empty(pairs)
    ia, ib = np.empty(pairs, dtype=np.int64), np.empty(pairs, dtype=np.int64)
    k = 0
    for i in range(m):
        for j in range(i + 1, m):
            d = angle_distance(q[i], q[j], periodic)
            if d <= reach:  # only pairs within reach are sorted and tried
                dist[k], ia[k], ib[k] = d, i, j
                k += 1
    dist = dist[:k]
    p, r = np.empty(3), np.empty((3, 3))
    jac, jm = np.empty((6, n)), np.empty((6, n))
    a, err, xs = np.empty((6, 6)), np.empty(6), np.empty(6)
    x, prev, delta = np.empty(n), np.empty(n), np.empty(n)
    chain, goal = (frames, lower, upper, periodic), (pos, rot, pose)
    work = (p, r, jac, jm, a, err, xs)
    timed = deadline < np.inf
    for k in np.argsort(dist):
        i, j = ia[k], ib[k]
        if root(parent, i) == root(parent, j):
            continue
        if timed and monotonic() > deadline:
            break
        count = max(1, int(math.ceil(dist[k] / step)))
        for c in range(n):
            v = q[j, c] - q[i, c]
            if periodic[c]:
                v -= TURN * np.rint(v * PER_TURN)
            delta[c] = v / count
        x[:] = q[i]
        ok = True
        for _ in range(count):
            prev[:] = x
            for c in range(n):
                x[c] += delta[c]
            _into_limits(x, lower, upper, periodic)
            if not correct(chain, x, goal, tols, work) or \
                    angle_distance(x, prev, periodic) > 2.0 * step:
                ok = False
                break
        if ok and angle_distance(x, q[j], periodic) < 2.0 * step:
            union(parent, i, j)
    return roots(parent)
