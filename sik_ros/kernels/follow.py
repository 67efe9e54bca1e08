"""Compiled path following: each row of a path's tracks refined onto its next waypoint.

:func:`follow_rows` takes each configuration from a step away onto its waypoint (the first
step on the Jacobian extrapolated to the step's midpoint); :func:`predict_rows` moves rows by
a tip motion through the damped inverse of their Jacobians. The damped least squares step
itself is :mod:`sik_ros.kernels.dls`'s.
"""


from numba import njit
import numpy as np

from sik_ros.kernels._cache import CACHE
from sik_ros.kernels.chain import F1, F2, F3, place, rotation_error
from sik_ros.kernels.clock import monotonic
from sik_ros.kernels.dls import damped_solve, limited_step

#: The fields of :func:`follow_rows`'s ``settings``, in order: the tolerances squared [m^2],
#: [rad^2], the damping squared, the largest joint step [rad], the most steps per row, the
#: deadline (a :func:`~sik_ros.kernels.clock.monotonic` time, inf for none), whether the goals
#: are poses (1) and whether there is one per row (1).
FOLLOW = ('tol2', 'otol2', 'damping2', 'max_step', 'iterations', 'deadline', 'pose', 'per_row')
(F_TOL2, F_OTOL2, F_DAMPING2, F_MAX_STEP, F_ITERATIONS, F_DEADLINE, F_POSE,
 F_PER_ROW) = range(len(FOLLOW))


@njit(f'void({F3}, {F1}, {F1}, {F2}, {F2}, {F3}, {F3}, {F3}, {F2}, {F3}, {F1}, int64[:, ::1])',
      cache=CACHE, nogil=True)
def follow_rows(frames, lower, upper, q, p, r, jac, djac, pos, rot, settings,
                outcome):  # pragma: no cover (compiled)
    """Rows near their goal refined onto it, their evaluations carried along (in place).

    ``settings``: float64 values named by :data:`FOLLOW` (below by their names). Each row's
    error comes from its evaluation ``p`` (M, 3), ``r`` (M, 3, 3), ``jac`` (M, 6, n); a row
    within the tolerances (squared: ``tol2`` [m^2], ``otol2`` [rad^2]) stops there, the others
    take a step (the first on ``jac + djac / 2``, the Jacobian extrapolated to the step's
    midpoint), no turns of periodic joints, and are evaluated again (``q``, ``p``, ``r``,
    ``jac`` updated in place), at most ``iterations`` steps. Goals: ``pos`` (G, 3), ``rot`` (G,
    3, 3), one per row (``per_row``) or one for all.

    Output ``outcome`` (2, M): 1 where the row ended within the tolerances (else 0), and the
    steps it took.
    """
    tol2, otol2, lam2 = settings[F_TOL2], settings[F_OTOL2], settings[F_DAMPING2]
    max_step, iterations = settings[F_MAX_STEP], int(settings[F_ITERATIONS])
    deadline = settings[F_DEADLINE]
    pose, per_row = settings[F_POSE] != 0, settings[F_PER_ROW] != 0
    ok, steps = outcome[0], outcome[1]
    m, n = q.shape
    dims = 6 if pose else 3
    timed = deadline < np.inf
    jm, a = np.empty((6, n)), np.empty((6, 6))
    err, x = np.empty(6), np.empty(6)
    j0 = np.empty((6, n))
    periodic = np.zeros(n, dtype=np.bool_)
    late = False
    bounds, step, scratch = (lower, upper, periodic), (lam2, max_step), (jm, a, x)
    for row in range(m):
        g = row if per_row else 0
        ok[row], steps[row] = 0, 0
        for it in range(iterations + 1):
            err[0] = pos[g, 0] - p[row, 0]
            err[1] = pos[g, 1] - p[row, 1]
            err[2] = pos[g, 2] - p[row, 2]
            good = err[0] * err[0] + err[1] * err[1] + err[2] * err[2] <= tol2
            if pose:
                oe = rotation_error(rot[g], r[row], err[3:])
                good = good and oe * oe <= otol2
            if good:
                ok[row] = 1
                break
            if it == iterations:
                break
            if timed and (late or monotonic() > deadline):
                late = True
                break
            if it == 0:
                for i in range(dims):
                    for j in range(n):
                        j0[i, j] = jac[row, i, j] + 0.5 * djac[row, i, j]
                limited_step(q[row], j0, err, dims, bounds, False, step, scratch)
            else:
                limited_step(q[row], jac[row], err, dims, bounds, False, step, scratch)
            place(frames, q[row], p[row], r[row], jac[row], True)
            steps[row] += 1


@njit(f'void({F2}, {F3}, {F3}, {F3}, int64, float64, {F1}, {F1}, {F3})', cache=CACHE,
      nogil=True)
def predict_rows(q, jac, djac, move, dims, lam2, lower, upper,
                 out):  # pragma: no cover (compiled)
    """Each track's configurations at the next waypoints, predicted to second order.

    Track ``t`` (``q`` (T, n), its Jacobian ``jac`` (T, 6, n) and change per step ``djac``)
    takes step ``k`` of ``move`` (m, T, dims) by damped least squares on the Jacobian
    extrapolated to the step's midpoint, ``jac + (k + 1/2) djac``; ``out`` (m, T, n): the
    steps summed, each within the limits.
    """
    m, t_count, n = move.shape[0], q.shape[0], q.shape[1]
    jm, a = np.empty((6, n)), np.empty((6, 6))
    x = np.empty(6)
    acc = np.empty(n)
    for t in range(t_count):
        for j in range(n):
            acc[j] = q[t, j]
        for k in range(m):
            mid = k + 0.5
            for i in range(dims):
                for j in range(n):
                    jm[i, j] = jac[t, i, j] + mid * djac[t, i, j]
            damped_solve(jm, move[k, t], dims, n, lam2, a, x)
            for j in range(n):
                s = 0.0
                for i in range(dims):
                    s += jm[i, j] * x[i]
                acc[j] += s
                out[k, t, j] = min(max(acc[j], lower[j]), upper[j])
