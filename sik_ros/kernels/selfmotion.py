"""Compiled self-motion of a redundant arm at a pose: the step along it.

A 7-joint arm reaches a 6-d pose along one-dimensional self-motion curves: closed loops, the
joint limits aside, which the limits cut into the pose's posture families (the pieces an
analytic solver sweeping one joint finds). Every kernel that moves along them takes its step
here:

- :func:`advance`: the predictor, a step along the unit null vector of the Jacobian, kept
  pointing the way the curve is followed; :func:`step_rows` does the same for a batch whose
  null vectors are given (the solver's walk);
- :func:`correct`: the corrector, damped least squares back onto the goal.

The curves traced with them into a pose's atlas of pieces: :mod:`sik_ros.kernels.atlas`.
"""

from numba import njit

from sik_ros.kernels._cache import CACHE
from sik_ros.kernels.chain import null_vector7, place
from sik_ros.kernels.dls import goal_error, limited_step

#: Most corrector iterations per point of a trace or a segment.
CORRECTIONS = 8
#: Squared damping of the corrector's steps [1].
CORRECT_DAMPING2 = 1e-8
#: The fields of a trace's ``settings`` (:func:`~sik_ros.kernels.atlas.trace_atlas`,
#: :func:`~sik_ros.kernels.families.trace_labels`), in order: the step along the curve [rad],
#: the most steps each way, the link distance [rad], the corrector's tolerances [m], [rad] and
#: largest joint step [rad], and the deadline (a :func:`~sik_ros.kernels.clock.monotonic`
#: time, inf for none).
TRACE = ('step', 'max_steps', 'link', 'position_tolerance', 'orientation_tolerance',
         'max_step', 'deadline')
T_STEP, T_MAX_STEPS, T_LINK, T_TOL_P, T_TOL_O, T_MAX_STEP, T_DEADLINE = range(len(TRACE))


@njit(cache=CACHE, nogil=True)
def correct(chain, x, goal, tols, work):  # pragma: no cover (compiled)
    """``x`` corrected onto the goal in place; whether it met the tolerances within limits.

    ``chain``: ``(frames, lower, upper, periodic)``; ``goal``: ``(pos, rot, pose)``; ``tols``:
    ``(tol_p, tol_o, max_step)``; ``work``: ``(p, r, jac, jm, a, err, xs)``, whose ``p``,
    ``r`` and ``jac`` are left those of ``x`` (a predictor may step from them).
    """
    frames, lower, upper, periodic = chain
    pos, rot, pose = goal
    tol_p, tol_o, max_step = tols
    p, r, jac, jm, a, err, xs = work
    bounds, step, scratch = (lower, upper, periodic), (CORRECT_DAMPING2, max_step), (jm, a, xs)
    dims = 6 if pose else 3
    for _ in range(CORRECTIONS):
        place(frames, x, p, r, jac, True)
        pe, oe = goal_error(pos, rot, pose, p, r, err)
        if pe < tol_p and (not pose or oe < tol_o):
            return True
        limited_step(x, jac, err, dims, bounds, True, step, scratch)
    place(frames, x, p, r, jac, True)
    pe, oe = goal_error(pos, rot, pose, p, r, err)
    return pe < tol_p and (not pose or oe < tol_o)


@njit(cache=CACHE, nogil=True)
def _step_along(x, v, heading, first, way, h):  # pragma: no cover (compiled)
    """``x`` moved ``h`` along ``v`` signed as ``way`` (``first``) or as ``heading``.

    ``heading`` becomes the signed unit vector: the way the curve is followed.
    """
    sign = way
    if not first:
        dot = 0.0
        for j in range(x.shape[0]):
            dot += v[j] * heading[j]
        sign = 1.0 if dot >= 0.0 else -1.0
    for j in range(x.shape[0]):
        heading[j] = sign * v[j]
        x[j] += h * heading[j]


@njit(cache=CACHE, nogil=True)
def advance(frames, x, heading, first, way, h, p, r, jac, minor, v,
            placed):  # pragma: no cover (compiled)
    """The predictor: ``x`` moved ``h`` [rad] along the null vector of its Jacobian.

    The unit null vector (of a 6 x 7 Jacobian) is signed as ``way`` on the ``first`` step,
    then to keep ``heading`` (updated). ``placed``: ``jac`` is already that of ``x`` (a
    corrector's last). Returns False where the Jacobian is singular.
    """
    if not placed:
        place(frames, x, p, r, jac, True)
    if not null_vector7(jac, minor, v):
        return False
    _step_along(x, v, heading, first, way, h)
    return True


@njit('void(float64[:, ::1], float64[:, ::1], float64[:, ::1], boolean, float64, float64[::1], '
      'float64[::1], float64[:, ::1])', cache=CACHE, nogil=True)
def step_rows(q, nvec, heading, first, h, lower, upper, out):  # pragma: no cover (compiled)
    """Each row of ``q`` moved ``h`` along its null vector ``nvec`` into ``out``, clipped.

    As :func:`advance`, the null vectors given (any arm): signed as given on the ``first``
    step, else to keep each row's ``heading``; ``nvec`` becomes the signed vectors.
    """
    for i in range(q.shape[0]):
        out[i] = q[i]
        _step_along(out[i], nvec[i], heading[i], first, 1.0, h)
        nvec[i] = heading[i]
        for j in range(q.shape[1]):
            out[i, j] = min(max(out[i, j], lower[j]), upper[j])
