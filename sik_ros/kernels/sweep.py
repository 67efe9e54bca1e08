"""Compiled search of a redundant arm's self-motion at a pose: the pieces within the limits.

A 7-joint arm reaches a pose along one-dimensional self-motion curves (closed loops, the
limits aside); the joint limits cut them into the pose's posture families, as an analytic
solver sweeping one joint finds them. Refinement and the walk from a known solution stay
within the limits, so a piece the limits part from it is not reached.
:func:`trace_pieces` follows each known solution's curve *past* the limits (angles turned by
whole turns only when the limits are checked) and returns a point of every piece within the
limits that holds none of the known solutions.
"""

import math

from numba import njit
import numpy as np

from sik_ros.kernels._cache import CACHE
from sik_ros.kernels.chain import null_vector7, place
from sik_ros.kernels.families import _correct, _distance
from sik_ros.kinematics.periodic import TURN

#: A free joint's bounds while a sheet is followed past the limits [rad].
FREE = 1e9
#: Times a trace's step is halved where the corrector fails (near a singularity) before the
#: trace ends there.
HALVINGS = 3


@njit(cache=CACHE, nogil=True)
def _wrapped(x, lower, upper, held, out):  # pragma: no cover (compiled)
    """``x`` with each joint but ``held`` turned by whole turns into its limits, into ``out``.

    Returns whether every joint fits (a joint whose range spans a turn always does).
    """
    ok = True
    for c in range(x.shape[0]):
        v = x[c]
        if c != held:
            v = lower[c] + (v - lower[c]) % TURN
            if v > upper[c]:
                ok = False
        out[c] = v
    return ok


@njit(cache=CACHE, nogil=True)
def _emit(run, length, out, owner, count, start):  # pragma: no cover (compiled)
    """The middle point of a run written as ``out[count]`` (room left); the new count."""
    if length == 0 or count >= out.shape[0]:
        return count
    out[count] = run[length // 2]
    owner[count] = start
    return count + 1


@njit(cache=CACHE, nogil=True)
def _trace(frames, lower, upper, start, q, pos, rot, step, max_steps, link, tol_p, tol_o,
           max_step, followed, trace, out, owner, count, row, work):  # pragma: no cover
    """One start's trace (:func:`trace_pieces`); returns the count of points written."""
    n = q.shape[1]
    lo, up, periodic, turns, p, r, jac, jm, a, err, xs, minor, v, heading, x, prev, inside, \
        run = work
    for way in (1.0, -1.0):
        x[:] = start
        length = 0  # the current run of points within the limits
        known = False  # the run holds a row of q
        h = step
        for s in range(max_steps):
            place(frames, x, p, r, jac, True)
            if not null_vector7(jac, minor, v):
                break
            sign = way
            if s > 0:
                dot = 0.0
                for j in range(n):
                    dot += v[j] * heading[j]
                sign = 1.0 if dot >= 0.0 else -1.0
            prev[:] = x
            for j in range(n):
                heading[j] = sign * v[j]
                x[j] += h * heading[j]
            if not _correct(frames, lo, up, periodic, x, pos, rot, True, tol_p, tol_o,
                            max_step, p, r, jac, jm, a, err, xs) or \
                    _distance(x, prev, periodic) > 2.0 * h:
                if h < step / 2 ** (HALVINGS - 0.5):
                    break
                x[:] = prev  # near a singularity: the step halved, the same heading
                h /= 2
                continue
            h = min(step, 2 * h)
            if s >= 2 and _distance(x, start, turns) < link:
                return count  # the loop closed (every angle modulo a turn): all seen
            if _wrapped(x, lower, upper, -1, inside):
                run[length] = inside
                length += 1
                for k in range(q.shape[0]):
                    if _distance(inside, q[k], periodic) < link:
                        known = True
                        followed[k] = trace
                continue
            if not known:
                count = _emit(run, length, out, owner, count, row)
            length = 0
            known = False
        if not known:
            count = _emit(run, length, out, owner, count, row)
    return count


@njit('int64(float64[:, :, ::1], float64[::1], float64[::1], float64[:, ::1], int64[::1], '
      'float64[::1], float64[:, ::1], float64, int64, float64, float64, float64, float64, '
      'float64[:, ::1], int64[::1])', cache=CACHE, nogil=True)
def trace_pieces(frames, lower, upper, q, flips, pos, rot, step, max_steps, link, tol_p,
                 tol_o, max_step, out, owner):  # pragma: no cover (compiled)
    """Points of the pieces within the limits of the self-motion through pose solutions ``q``.

    ``q`` (M, 7): the exact solutions of a 7-joint arm known at a pose (position ``pos`` (3,)
    [m], rotation ``rot`` (3, 3), tolerances ``tol_p`` [m], ``tol_o`` [rad]). From each row
    no earlier trace passed (within ``link`` [rad]), and from its flips (``flips``: the first
    joints of :func:`~sik_ros.kinematics.branches.exact_flips`' triples: configurations at
    the same pose, maybe on another loop), the self-motion curve is followed both ways in
    steps of ``step`` [rad] *free of the limits* (predictor along the null vector of the
    Jacobian, corrector onto the pose) until it closes on its start (every angle modulo a
    turn), meets a row an earlier trace passed (its loop is known), fails (a singularity) or
    has taken ``max_steps``. Each maximal run of points within the limits (every angle turned
    by whole turns into them) that comes within ``link`` of no row of ``q`` gives one point,
    its middle one, written to ``out`` (K, 7) with the row it was followed from in ``owner``
    (K,).

    Returns:
        how many points were written (at most K).
    """
    m, n = q.shape[0], q.shape[1]
    work = (np.full(n, -FREE), np.full(n, FREE), np.zeros(n, dtype=np.bool_),
            np.ones(n, dtype=np.bool_), np.empty(3), np.empty((3, 3)), np.empty((6, n)),
            np.empty((6, n)), np.empty((6, 6)), np.empty(6), np.empty(6), np.empty((6, 6)),
            np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n),
            np.empty((max_steps, n)))
    followed = np.zeros(m, dtype=np.int64)  # the trace (from 1) that passed each row
    start = np.empty(n)
    count = 0
    trace = 0
    for i in range(m):
        if followed[i] != 0:
            continue
        for f in range(-1, flips.shape[0]):
            start[:] = q[i]
            if f >= 0:
                c = flips[f]
                start[c] += math.pi
                start[c + 1] = -start[c + 1]
                start[c + 2] += math.pi
            trace += 1
            count = _trace(frames, lower, upper, start, q, pos, rot, step, max_steps, link,
                           tol_p, tol_o, max_step, followed, trace, out, owner, count, i, work)
    return count
