"""Compiled atlas of a redundant arm's self-motion at a pose: its curves traced into pieces.

:func:`trace_atlas`: each known solution's curve (and its exact flips') followed *past* the
limits until it closes, with the step of :mod:`sik_ros.kernels.selfmotion`, every point within
the limits recorded with its piece: the pose's atlas. Its pieces are the families. The atlas
read (points far apart on each piece, the piece of any solution):
:mod:`sik_ros.kernels.atlas_points`.
"""

import math

from numba import njit
import numpy as np

from sik_ros.kernels._cache import CACHE
from sik_ros.kernels.angles import angle_distance, flip_triple, PER_TURN, TURN, turned_into
from sik_ros.kernels.clock import monotonic
from sik_ros.kernels.selfmotion import (advance, correct, T_DEADLINE, T_LINK, T_MAX_STEP,
                                        T_MAX_STEPS, T_STEP, T_TOL_O, T_TOL_P)
from sik_ros.kernels.sets import root, union

#: A free joint's bounds while a curve is followed past the limits [rad].
FREE = 1e9
#: Most a trace's corrector may move a predicted point, as a share of the step: farther, it
#: may have landed on another curve passing near (the step is halved).
DRIFT = 0.5
#: A step whose corrector moved the point more than this share of the step has the middle
#: of its chord corrected too (:data:`MIDPOINT`).
CHECK_DRIFT = 0.15
#: Most the corrector may move the middle of a checked step's chord, as a share of the step:
#: farther, the step crossed from one curve to another passing near it (near a singularity,
#: where the corrector lands on either) and is halved.
MIDPOINT = 0.25
#: A trace closes where it comes back within a link of its start only after this many links
#: along the curve: by a singularity its first steps are short (halved) and stay that near.
CLOSE = 2.0
#: Recorded points closer than this share of the step may be one curve traced twice...
SAME_POINT = 0.6
#: ... and are, when one lies this close (a share of the step) to the other's chords: a
#: curve traced twice lies on its first trace's chords, a curve passing near another (by a
#: singularity) crosses them at most at one point and leaves them.
ON_CHORDS = 0.4
#: Times a trace's step is halved where the corrector fails (near a singularity) before the
#: trace ends there.
HALVINGS = 3
#: Outside the limits a trace's step is no longer than how far outside it is (a joint moves no
#: more than the step), but at least this share of the step: a sliver of a curve within the
#: limits is seldom stepped over.
NEAR_LIMITS = 0.5


@njit(cache=CACHE, nogil=True)
def _near(x, rows, count, link, periodic):  # pragma: no cover (compiled)
    """The first of the first ``count`` rows within ``link`` of ``x``, or -1."""
    for k in range(count):
        if angle_distance(x, rows[k], periodic) < link:
            return k
    return -1


@njit(cache=CACHE, nogil=True)
def _off_chords(x, points, piece, count, j, step, periodic):  # pragma: no cover (compiled)
    """How far [rad] ``x`` lies from the chords of recorded point ``j`` to its neighbours.

    Its neighbours: the points recorded just before and after it on its piece, within 1.5
    steps of it (a trace's consecutive points; the first point of a trace's second way
    follows its start's, not the last point's).
    """
    best = angle_distance(x, points[j], periodic)
    for k in (j - 1, j + 1):
        if k < 0 or k >= count or piece[k] != piece[j]:
            continue
        ee = dd = de = 0.0
        for c in range(x.shape[0]):
            e = points[k, c] - points[j, c]
            d = x[c] - points[j, c]
            if periodic[c]:
                e -= TURN * np.rint(e * PER_TURN)
                d -= TURN * np.rint(d * PER_TURN)
            ee += e * e
            dd += d * d
            de += d * e
        if ee == 0.0 or ee > (1.5 * step) ** 2:
            continue
        t = min(max(de / ee, 0.0), 1.0)
        best = min(best, math.sqrt(max(dd - 2.0 * t * de + t * t * ee, 0.0)))
    return best


@njit(cache=CACHE, nogil=True)
def _record(inside, cur, q, periodic, link, points, piece, count, row_piece,
            row_dist):  # pragma: no cover (compiled)
    """A point within the limits recorded on piece ``cur``; rows near it take its piece.

    A row within ``link`` of it takes its piece when it is the row's nearest recorded point
    yet (``row_dist``): a row between two curves that pass near (by a singularity) lies on
    one of them and joins neither to the other.
    """
    if count < points.shape[0]:
        points[count] = inside
        piece[count] = cur
        count += 1
    for k in range(q.shape[0]):
        d = angle_distance(inside, q[k], periodic)
        if d < link and d < row_dist[k]:
            row_piece[k] = cur
            row_dist[k] = d
    return count


@njit(cache=CACHE, nogil=True)
def _outside_by(x, lower, upper):  # pragma: no cover (compiled)
    """How far [rad] ``x`` lies outside the limits: its largest joint's, turned (0: inside)."""
    out = 0.0
    for j in range(x.shape[0]):
        v = lower[j] + (x[j] - lower[j]) % TURN
        if v > upper[j]:
            out = max(out, min(v - upper[j], lower[j] + TURN - v))
    return out


@njit(cache=CACHE, nogil=True)
def _jumped(chain, prev, x, goal, tols, h, mid, chord, work):  # pragma: no cover (compiled)
    """Whether a step of ``h`` from ``prev`` to ``x`` crossed from one curve to another.

    The middle of the chord, corrected onto the pose, lies near it on one smooth curve; it
    lands farther than :data:`MIDPOINT` steps away (or nowhere) where the chord joins two
    curves passing near each other. ``chain``, ``goal``, ``tols``, ``work``: the corrector's
    (:func:`~sik_ros.kernels.selfmotion.correct`); ``mid``, ``chord``: work space.
    """
    free = chain[3]
    for j in range(x.shape[0]):
        mid[j] = 0.5 * (prev[j] + x[j])
        chord[j] = mid[j]
    if not correct(chain, mid, goal, tols, work):
        return True
    return angle_distance(mid, chord, free) > MIDPOINT * h


@njit(cache=CACHE, nogil=True)
def _crossed(x, prev, flips):  # pragma: no cover (compiled)
    """Whether a step from ``prev`` to ``x`` took a flip's middle joint through 0 or pi.

    No self-motion curve does (there the flip's triple is singular, and its twin curve
    passes near): the corrector landed on the twin.
    """
    for f in range(flips.shape[0]):
        if math.sin(x[flips[f] + 1]) * math.sin(prev[flips[f] + 1]) < 0.0:
            return True
    return False


@njit(cache=CACHE, nogil=True)
def _twins(path, length, flips, bounds, link, q, record, count, pieces,
           scratch):  # pragma: no cover (compiled)
    """The twins of a closed traced curve recorded: its exact flips, curves of their own.

    ``path[:length]``: the curve's points in order, free of the limits. Twin ``t`` (1 .. 2^F
    - 1) flips the triples of its set bits (``flips``); its points within the limits
    (``bounds``: ``(lower, upper, periodic)``) are recorded as the trace's are (``record``:
    ``(points, piece, row_piece, row_dist, parent)``), its last piece joined to its first (the
    twin closes too). ``scratch``: ``(y, inside)``. Returns the count and the pieces numbered.
    """
    lower, upper, periodic = bounds
    points, piece, row_piece, row_dist, parent = record
    y, inside = scratch
    for t in range(1, 1 << flips.shape[0]):
        cur, first = -1, -1
        for k in range(length):
            y[:] = path[k]
            for f in range(flips.shape[0]):
                if t >> f & 1:
                    flip_triple(y, flips[f])
            if turned_into(y, lower, upper, inside):
                if cur < 0:
                    cur = pieces
                    pieces += 1
                    if k == 0:
                        first = cur
                count = _record(inside, cur, q, periodic, link, points, piece, count,
                                row_piece, row_dist)
            else:
                cur = -1
        if cur >= 0 and first >= 0:
            union(parent, cur, first)
    return count, pieces


@njit('int64(float64[:, :, ::1], float64[::1], float64[::1], boolean[::1], float64[:, ::1], '
      'int64[::1], float64[::1], float64[:, ::1], float64[::1], float64[:, ::1], int64[::1], '
      'int64[::1])', cache=CACHE, nogil=True)
def trace_atlas(frames, lower, upper, periodic, q, flips, pos, rot, settings, points, piece,
                row_piece):  # pragma: no cover (compiled)
    """The atlas of a 7-joint arm's self-motion at a pose through its known solutions ``q``.

    ``settings``: float64 values named by :data:`~sik_ros.kernels.selfmotion.TRACE` (below by
    their names). ``q`` (M, 7): exact solutions at the pose (position ``pos`` (3,) [m],
    rotation ``rot`` (3, 3), tolerances ``tol_p`` [m], ``tol_o`` [rad]). From each row no
    earlier trace passed (within ``link`` [rad]) the curve is followed both ways in steps of
    ``step`` [rad] *free of the limits* (:func:`advance`, then :func:`correct`; the step halved
    up to :data:`HALVINGS` times where the corrector fails or moves the point more than
    :data:`DRIFT` steps, near a singularity or another curve, or where the step crossed to
    another curve passing near, :func:`_jumped`; outside the limits shortened to how far
    outside it is, :data:`NEAR_LIMITS`) until it closes on its start (after :data:`CLOSE`
    links) (every angle modulo a turn), fails or has taken ``max_steps``. Every point, its
    angles turned by whole turns into the limits where they fit, is recorded in ``points`` (P,
    7) with its piece in ``piece`` (P,): consecutive points within the limits are one piece,
    and pieces a closed curve joins are one. The arm's exact flips (``flips``: the first joints
    of :func:`~sik_ros.kinematics.branches.exact_flips`' triples) map a curve onto its twins,
    other curves at the pose: a closed curve's twins are recorded from its points flipped
    (:func:`_twins`), without a trace; where a trace does not close (it ends near a
    singularity), the row's flips are traced as rows are, unless they lie on a recorded curve.
    ``row_piece`` (M,): each row's piece, that of its nearest recorded point within ``link``
    (-1: none reached it). Piece numbers are resolved to the smallest of their joined set. Past
    ``deadline`` (a :func:`~sik_ros.kernels.clock.monotonic` time) no trace goes on.

    Returns:
        how many points were recorded (at most P; the traces stop when ``points`` is full).
    """
    step, max_steps, link = settings[T_STEP], int(settings[T_MAX_STEPS]), settings[T_LINK]
    tol_p, tol_o = settings[T_TOL_P], settings[T_TOL_O]
    max_step, deadline = settings[T_MAX_STEP], settings[T_DEADLINE]
    m, n = q.shape[0], q.shape[1]
    lo, up = np.full(n, -FREE), np.full(n, FREE)
    free, turns = np.zeros(n, dtype=np.bool_), np.ones(n, dtype=np.bool_)
    p, r = np.empty(3), np.empty((3, 3))
    jac, jm = np.empty((6, n)), np.empty((6, n))
    a, err, xs, minor = np.empty((6, 6)), np.empty(6), np.empty(6), np.empty((6, 6))
    v, heading, x, prev = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    start, inside, predicted, y = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    mid, p_mid, r_mid, jac_mid = np.empty(n), np.empty(3), np.empty((3, 3)), np.empty((6, n))
    path = np.empty((max_steps + 1, n))
    parent = np.arange(points.shape[0])
    free_chain = (frames, lo, up, free)  # the corrector free of the limits
    goal, tols = (pos, rot, True), (tol_p, tol_o, max_step)
    work, mid_work = (p, r, jac, jm, a, err, xs), (p_mid, r_mid, jac_mid, jm, a, err, xs)
    row_piece[:] = -1
    row_dist = np.full(m, np.inf)
    count, pieces = 0, 0
    timed = deadline < np.inf
    full = points.shape[0]
    for i in range(m):
        if row_piece[i] >= 0:
            continue
        twinned = False
        for f in range(-1, flips.shape[0]):
            start[:] = q[i]
            if f >= 0:
                if twinned:
                    break  # the flips' curves are recorded
                flip_triple(start, flips[f])
                if turned_into(start, lower, upper, inside) and \
                        _near(inside, points, count, link, periodic) >= 0:
                    continue  # a curve already traced
            first_piece = -1
            pending = False  # the start, recorded once a step from it holds
            closed = False
            length = 0
            for way in (1.0, -1.0):
                if closed or count >= full:
                    break
                x[:] = start
                cur = -1
                home = False  # on the start's piece (numbered at its first record)
                if turned_into(x, lower, upper, inside):
                    home = True
                    cur = first_piece
                    pending = pending or way > 0
                if way > 0:
                    path[0] = x
                    length = 1
                h = step
                placed = False
                travelled = 0.0  # along the curve this way [rad]
                for s in range(max_steps):
                    if (timed and monotonic() > deadline) or count >= full:
                        break
                    prev[:] = x
                    if not advance(frames, x, heading, s == 0, way, h, p, r, jac, minor, v,
                                   placed):
                        break
                    placed = False
                    predicted[:] = x
                    on = correct(free_chain, x, goal, tols, work)
                    moved = angle_distance(x, predicted, free)  # by the corrector
                    if not on or moved > DRIFT * h or _crossed(x, prev, flips) or \
                            (moved > CHECK_DRIFT * h and
                             _jumped(free_chain, prev, x, goal, tols, h, mid, y, mid_work)):
                        if h < step / 2 ** (HALVINGS - 0.5):
                            break
                        x[:] = prev  # near a singularity: the step halved, the same heading
                        h /= 2
                        continue
                    travelled += h
                    h = min(step, 2 * h)
                    placed = True
                    if pending:  # a start no step leaves (by a singularity) is no piece
                        if first_piece < 0:
                            first_piece = pieces
                            pieces += 1
                        if home:
                            cur = first_piece
                        turned_into(start, lower, upper, predicted)
                        count = _record(predicted, first_piece, q, periodic, link, points,
                                        piece, count, row_piece, row_dist)
                        pending = False
                    if travelled > CLOSE * link and angle_distance(x, start, turns) < link:
                        if cur >= 0 and first_piece >= 0:
                            union(parent, cur, first_piece)
                        closed = True
                        break
                    if way > 0 and length < path.shape[0]:
                        path[length] = x
                        length += 1
                    if turned_into(x, lower, upper, inside):
                        if cur < 0:
                            cur = pieces
                            pieces += 1
                            if home:
                                first_piece = cur
                        count = _record(inside, cur, q, periodic, link, points, piece, count,
                                        row_piece, row_dist)
                    else:
                        cur = -1
                        home = False
                        h = min(h, max(_outside_by(x, lower, upper), NEAR_LIMITS * step))
            if f < 0 and closed and flips.shape[0] > 0:
                count, pieces = _twins(path, length, flips, (lower, upper, periodic), link,
                                       q, (points, piece, row_piece, row_dist, parent),
                                       count, pieces, (y, inside))
                twinned = True
    # a curve recorded twice (traced through a point where two curves nearly meet, near a
    # singularity, from one and from the other): its two records are one
    same, on = SAME_POINT * step, ON_CHORDS * step
    for k in range(count):
        for j in range(k):
            if piece[j] != piece[k] and \
                    angle_distance(points[k], points[j], periodic) < same and \
                    _off_chords(points[k], points, piece, count, j, step, periodic) < on:
                union(parent, piece[j], piece[k])
    for k in range(count):
        piece[k] = root(parent, piece[k])
    for i in range(m):
        if row_piece[i] >= 0:
            row_piece[i] = root(parent, row_piece[i])
    return count
