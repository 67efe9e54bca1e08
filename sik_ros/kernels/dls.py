"""Compiled damped least squares: refinement and path following, row by row.

Every row (a starting configuration) takes steps ``J^T (J J^T + lambda^2 I)^-1 e`` on the
chain's Jacobian (:mod:`sik_ros.kernels.chain`) until it stops; then the next row starts. Joints
at a limit that the descent direction pushes further out leave the step (active set), a step is
scaled down to ``max_step`` on its largest joint, and while solving (not following a path) a
periodic joint stepping past a limit is turned back by 2 pi. A row stops when it converges, when
it stalls or stays far from the goal, when it heads for a solution an earlier row found
(pruning), or at the deadline; :func:`refine_rows` stops every row once ``enough`` distinct rows
converged. The kernels release the GIL: threads solve in parallel.
"""

import math

from numba import njit
import numpy as np

from sik_ros.kernels._cache import CACHE
from sik_ros.kernels.angles import turn_once
from sik_ros.kernels.chain import F1, F2, F3, place, rotation_error
from sik_ros.kernels.clock import monotonic

#: Row outcomes of :func:`refine_rows` (``status``).
UNTOUCHED, CONVERGED, GIVEN_UP, ITERATIONS, PRUNED, DEADLINE = range(6)
#: The fields of :func:`refine_rows`'s ``reals`` and ``ints`` arguments, in order (a settings
#: record: :func:`sik_ros.solver.refine.kernel_settings` fills it by name, the kernels read it
#: through the positions below).
REALS = ('position_tolerance', 'orientation_tolerance', 'damping2', 'max_step', 'stall_ratio',
         'prune_radius', 'distinct_threshold', 'deadline', 'orientation_weight',
         'converge_factor', 'give_up_factor')
INTS = ('iterations', 'stall_window', 'stall_after', 'give_up_after', 'enough', 'prune',
        'roll_free', 'pose')
(R_TOL_P, R_TOL_O, R_DAMPING2, R_MAX_STEP, R_STALL_RATIO, R_PRUNE_RADIUS, R_DISTINCT,
 R_DEADLINE, R_WEIGHT, R_CONVERGE, R_GIVE_UP) = range(len(REALS))
(I_ITERATIONS, I_STALL_WINDOW, I_STALL_AFTER, I_GIVE_UP_AFTER, I_ENOUGH, I_PRUNE,
 I_ROLL_FREE, I_POSE) = range(len(INTS))
#: ``ints`` goes on past :data:`INTS` with the iterations at which rows are pruned.
PRUNE_AT = len(INTS)
#: The fields of :func:`polish_rows`'s ``settings``, in order.
POLISH = ('position_tolerance', 'orientation_tolerance', 'damping2', 'max_step',
          'orientation_weight', 'iterations')
P_TOL_P, P_TOL_O, P_DAMPING2, P_MAX_STEP, P_WEIGHT, P_ITERATIONS = range(len(POLISH))


@njit(cache=CACHE, nogil=True)
def goal_error(pos, rot, pose, p, r, err):  # pragma: no cover (compiled)
    """``err`` (6,): the position error (and rotation vector) to the goal; their norms."""
    err[0], err[1], err[2] = pos[0] - p[0], pos[1] - p[1], pos[2] - p[2]
    perr = math.sqrt(err[0] * err[0] + err[1] * err[1] + err[2] * err[2])
    oerr = rotation_error(rot, r, err[3:]) if pose else 0.0
    return perr, oerr


@njit(f'void({F3}, {F2}, {F1}, {F2}, boolean, {F1}, {F1})', cache=CACHE, nogil=True)
def goal_errors_rows(frames, q, pos, rot, pose, perr, oerr):  # pragma: no cover (compiled)
    """:func:`goal_error`'s norms for each row of ``q`` (M, n): ``perr``, ``oerr`` (M,).

    The measure refinement reports (``oerr`` 0 unless ``pose``).
    """
    p, r, err, no_jac = np.empty(3), np.empty((3, 3)), np.empty(6), np.empty((6, 0))
    for k in range(q.shape[0]):
        place(frames, q[k], p, r, no_jac, False)
        perr[k], oerr[k] = goal_error(pos, rot, pose, p, r, err)


@njit(cache=CACHE, nogil=True)
def damped_solve(jm, err, dims, n, lam2, a, x):  # pragma: no cover (compiled)
    """``x`` (dims,) = (J J^T + lambda^2 I)^-1 ``err`` for ``J`` = ``jm[:dims, :n]``, in place.

    By Cholesky (``a`` (6, 6): work array, left holding the factor).
    """
    for i in range(dims):
        for k in range(i + 1):
            s = 0.0
            for j in range(n):
                s += jm[i, j] * jm[k, j]
            a[i, k] = s
        a[i, i] += lam2
    for j in range(dims):
        s = a[j, j]
        for k in range(j):
            s -= a[j, k] * a[j, k]
        d = math.sqrt(s)
        a[j, j] = d
        for i in range(j + 1, dims):
            s = a[i, j]
            for k in range(j):
                s -= a[i, k] * a[j, k]
            a[i, j] = s / d
    for i in range(dims):
        s = err[i]
        for k in range(i):
            s -= a[i, k] * x[k]
        x[i] = s / a[i, i]
    for i in range(dims - 1, -1, -1):
        s = x[i]
        for k in range(i + 1, dims):
            s -= a[k, i] * x[k]
        x[i] = s / a[i, i]


@njit(cache=CACHE, nogil=True)
def limited_step(q, jac, err, dims, bounds, turn, step, scratch):  # pragma: no cover (compiled)
    """``q`` (n,) after one damped least squares step on ``err``, within the limits (in place).

    ``bounds``: ``(lower, upper, periodic)``; ``turn``: periodic joints past a limit turned
    back by 2 pi; ``step``: ``(damping squared, largest joint step)``; ``scratch``: the work
    arrays ``(jm (6, n), a (6, 6), x (6,))``. ``jac`` is left as it is.
    """
    lower, upper, periodic = bounds
    lam2, max_step = step
    jm, a, x = scratch
    n = q.shape[0]
    for j in range(n):
        free = not (turn and periodic[j])
        blocked = False
        if free and (q[j] <= lower[j] + 1e-9 or q[j] >= upper[j] - 1e-9):
            g = 0.0
            for i in range(dims):
                g += jac[i, j] * err[i]
            blocked = (q[j] <= lower[j] + 1e-9 and g < 0.0) or \
                (q[j] >= upper[j] - 1e-9 and g > 0.0)
        for i in range(dims):
            jm[i, j] = 0.0 if blocked else jac[i, j]
    damped_solve(jm, err, dims, n, lam2, a, x)
    biggest = 0.0
    for j in range(n):
        s = 0.0
        for i in range(dims):
            s += jm[i, j] * x[i]
        jm[0, j] = s  # the step, kept in the first row
        biggest = max(biggest, abs(s))
    scale = 1.0 / max(1.0, biggest / max_step)
    for j in range(n):
        v = q[j] + jm[0, j] * scale
        if turn and periodic[j]:
            v = turn_once(v, lower[j], upper[j])
        q[j] = min(max(v, lower[j]), upper[j])


@njit(cache=CACHE, nogil=True)
def _near_better(q, row, score, status, radius, cols):  # pragma: no cover (compiled)
    """Whether an earlier row (not given up) with a lower score lies within ``radius``."""
    for k in range(row):
        if status[k] == GIVEN_UP or status[k] == UNTOUCHED or score[k] > score[row]:
            continue
        d = 0.0
        for j in range(cols):
            v = q[row, j] - q[k, j]
            d += v * v
        if d < radius * radius:
            return True
    return False


@njit(cache=CACHE, nogil=True)
def _refine_row(chain, q, row, goal, settings, out, state, work):  # pragma: no cover (compiled)
    """Row ``row`` of :func:`refine_rows` refined until it stops; whether the deadline did.

    ``chain``: ``(frames, lower, upper, periodic)``; ``goal``: ``(pos, rot, pose)``;
    ``settings``: ``(reals, ints)``; ``out``: ``(perr, oerr, status)``; ``state``: ``(score,
    stale, history)``, the rows' scores, whether their errors are out of date and the row's
    recent scores; ``work``: ``(p, r, jac, jm, a, err, x)``, work arrays.
    """
    frames, lower, upper, periodic = chain
    pos, rot, pose = goal
    reals, ints = settings
    perr, oerr, status = out
    score, stale, history = state
    p, r, jac, jm, a, err, x = work
    prune_at = ints[PRUNE_AT:]
    tol_p, tol_o = reals[R_TOL_P], reals[R_TOL_O]
    lam2, max_step = reals[R_DAMPING2], reals[R_MAX_STEP]
    radius, deadline, weight = reals[R_PRUNE_RADIUS], reals[R_DEADLINE], reals[R_WEIGHT]
    converge, give_up = reals[R_CONVERGE], reals[R_GIVE_UP]
    iterations, prune = ints[I_ITERATIONS], ints[I_PRUNE] != 0
    n = q.shape[1]
    dims = 6 if pose else 3
    cols = n - 1 if ints[I_ROLL_FREE] != 0 else n
    timed = deadline < np.inf
    qi = q[row]
    bounds, step, scratch = (lower, upper, periodic), (lam2, max_step), (jm, a, x)
    status[row] = ITERATIONS
    history[:] = np.inf
    for it in range(iterations):
        if prune and _prune_now(prune_at, it) and \
                _near_better(q, row, score, status, radius, cols):
            status[row] = PRUNED
            break
        if timed and monotonic() > deadline:
            status[row] = DEADLINE
            return True
        place(frames, qi, p, r, jac, True)
        pe, oe = goal_error(pos, rot, pose, p, r, err)
        perr[row], oerr[row] = pe, oe
        stale[row] = False
        s = pe + weight * oe
        score[row] = s
        done = pe < tol_p * converge and (not pose or oe < tol_o * converge)
        stuck = pe > give_up * tol_p or (pose and oe > give_up * tol_o)
        verdict = _verdict(it, s, done, stuck, history, ints[I_STALL_WINDOW],
                           ints[I_STALL_AFTER], reals[R_STALL_RATIO], ints[I_GIVE_UP_AFTER])
        if verdict != ITERATIONS:
            status[row] = verdict
            break
        limited_step(qi, jac, err, dims, bounds, True, step, scratch)
        stale[row] = True
    return False


@njit(cache=CACHE, nogil=True)
def _prune_now(prune_at, it):  # pragma: no cover (compiled)
    """Whether iteration ``it`` is one of ``prune_at``."""
    hit = False
    for v in prune_at:
        hit = hit or v == it
    return hit


@njit(cache=CACHE, nogil=True)
def _verdict(it, s, done, stuck, history, window, stall_after, stall_ratio,
             give_up_after):  # pragma: no cover (compiled)
    """A row's outcome after iteration ``it`` at score ``s``: go on (ITERATIONS) or stop.

    It stalls when hardly closer than ``window`` iterations ago (``history`` keeps its
    scores), is given up when stalled or, from ``give_up_after`` on, still far (``stuck``).
    """
    stalled = False
    if window > 0:
        if it >= max(window, stall_after):
            # hardly closer than ``window`` iterations ago
            stalled = not done and s > stall_ratio * history[it % window]
        history[it % window] = s
    if it >= give_up_after or stalled:
        stuck = stalled if it < give_up_after else (stuck or stalled)
        if stuck and not done:
            return GIVEN_UP
    if done:
        return CONVERGED
    return ITERATIONS


@njit(cache=CACHE, nogil=True)
def _is_new(q, row, found, nfound, distinct, cols):  # pragma: no cover (compiled)
    """Whether row ``row`` is at least ``distinct`` from every row of ``found[:nfound]``."""
    qi = q[row]
    for k in range(nfound):
        d = 0.0
        for j in range(cols):
            v = qi[j] - q[found[k], j]
            d += v * v
        if d < distinct * distinct:
            return False
    return True


@njit(f'boolean({F3}, {F1}, {F1}, boolean[::1], {F2}, {F1}, {F2}, {F1}, int64[::1], {F1}, '
      f'{F1}, int8[::1])', cache=CACHE, nogil=True)
def refine_rows(frames, lower, upper, periodic, q, pos, rot, reals, ints, perr, oerr,
                status):  # pragma: no cover (compiled)
    """Damped least squares from each row of ``q`` (M, n) towards a goal, in place.

    Args:
        frames: the chain (:func:`~sik_ros.kernels.chain.chain_frames`).
        lower, upper: joint limits (n,) [rad]; periodic: (n,) bool, joints spanning a turn.
        q: starts (M, n) [rad], refined in place, row by row in order.
        pos: goal position (3,) [m]; rot: goal rotation (3, 3) (read for a pose goal:
            ``ints``' ``pose`` 1).
        reals: float64 values named by :data:`REALS` (``damping2``: the damping squared;
            ``deadline``: a ``time.perf_counter()`` value, inf for none;
            ``orientation_weight``: metres of a row's score per radian of orientation error).
        ints: int64 values named by :data:`INTS` (``enough`` 0: no early stop; ``prune`` and
            ``roll_free`` 0 or 1: the last joint left out of the distances; ``pose`` 1: a
            pose goal), then (from :data:`PRUNE_AT`) the iterations at which a row near an
            earlier, better one stops.
        perr, oerr: out (M,): the rows' position [m] and orientation [rad] errors.
        status: out (M,) int8, each row's outcome (:data:`CONVERGED`, ...).

    Returns:
        whether the deadline stopped refinement before every row had finished.
    """
    enough, distinct = ints[I_ENOUGH], reals[R_DISTINCT]
    pose = ints[I_POSE] != 0
    m, n = q.shape
    cols = n - 1 if ints[I_ROLL_FREE] != 0 else n
    p, r = np.empty(3), np.empty((3, 3))
    jac, jm, a = np.empty((6, n)), np.empty((6, n)), np.empty((6, 6))
    err, x = np.empty(6), np.empty(6)
    history = np.empty(max(ints[I_STALL_WINDOW], 1))
    score = np.full(m, np.inf)
    found = np.empty(m, dtype=np.int64)
    stale = np.ones(m, dtype=np.bool_)
    nfound = 0
    cut = False
    for row in range(m):
        status[row] = UNTOUCHED
        perr[row], oerr[row] = np.inf, 0.0
    chain, goal, settings = (frames, lower, upper, periodic), (pos, rot, pose), (reals, ints)
    out, state = (perr, oerr, status), (score, stale, history)
    work = (p, r, jac, jm, a, err, x)
    for row in range(m):
        if cut or (enough > 0 and nfound >= enough):
            break
        cut = _refine_row(chain, q, row, goal, settings, out, state, work)
        if status[row] == CONVERGED and enough > 0 and \
                _is_new(q, row, found, nfound, distinct, cols):
            found[nfound] = row
            nfound += 1
    for row in range(m):
        if stale[row]:
            place(frames, q[row], p, r, jac, False)
            perr[row], oerr[row] = goal_error(pos, rot, pose, p, r, err)
    return cut


@njit(f'void({F3}, {F1}, {F1}, boolean[::1], {F2}, int64[::1], {F1}, {F2}, {F1}, {F1}, {F1}, '
      f'{F1})', cache=CACHE, nogil=True)
def polish_rows(frames, lower, upper, periodic, q, rows, pos, rot, settings, perr, oerr,
                moved):  # pragma: no cover (compiled)
    """Rows ``rows`` of ``q`` (M, n) taken closer onto a pose goal, in place where it helps.

    ``settings``: float64 values named by :data:`POLISH`. Each row takes damped least squares
    steps (damping squared ``damping2``, within the limits, periodic joints turned back past a
    limit) until its errors are under ``position_tolerance`` [m] and ``orientation_tolerance``
    [rad], at most ``iterations`` steps. It is kept only where its score (``perr + weight *
    oerr``) ends lower than it was, with ``perr``, ``oerr`` (M,) updated; ``moved``
    (len(rows),): how far each kept row moved [rad] (0 where it was left as it was).
    """
    tol_p, tol_o = settings[P_TOL_P], settings[P_TOL_O]
    lam2, max_step, weight = settings[P_DAMPING2], settings[P_MAX_STEP], settings[P_WEIGHT]
    iterations = int(settings[P_ITERATIONS])
    n = q.shape[1]
    p, r = np.empty(3), np.empty((3, 3))
    jac, jm, a = np.empty((6, n)), np.empty((6, n)), np.empty((6, 6))
    err, x = np.empty(6), np.empty(6)
    qi = np.empty(n)
    bounds, step, scratch = (lower, upper, periodic), (lam2, max_step), (jm, a, x)
    for k in range(rows.shape[0]):
        row = rows[k]
        moved[k] = 0.0
        for j in range(n):
            qi[j] = q[row, j]
        pe, oe = perr[row], oerr[row]
        for it in range(iterations + 1):
            place(frames, qi, p, r, jac, True)
            pe, oe = goal_error(pos, rot, True, p, r, err)
            if (pe < tol_p and oe < tol_o) or it == iterations:
                break
            limited_step(qi, jac, err, 6, bounds, True, step, scratch)
        if pe + weight * oe < perr[row] + weight * oerr[row]:
            d = 0.0
            for j in range(n):
                d += (qi[j] - q[row, j]) ** 2
                q[row, j] = qi[j]
            perr[row], oerr[row], moved[k] = pe, oe, math.sqrt(d)
