"""Compiled angles of revolute joints: one turn, distances modulo a turn, flips, limits.

Every kernel that turns an angle, measures a distance with periodic joints at their nearest
turn or flips a spherical triple does it here (:mod:`sik_ros.kinematics.periodic` says which
joints are periodic and what follows for the solver).
"""

import math

from numba import njit
import numpy as np

from sik_ros.kernels._cache import CACHE

#: One turn [rad].
TURN = 2 * math.pi
#: Turns per radian [1/rad] (the kernels multiply by it rather than divide by :data:`TURN`).
PER_TURN = 0.5 / math.pi
#: A turned value this far outside a limit still fits it [rad] (rounding of the turn).
LIMIT_SLACK = 1e-9


@njit(cache=CACHE, nogil=True)
def turn_once(v, lower, upper):  # pragma: no cover (compiled)
    """``v`` turned by one turn towards ``lower``..``upper`` when it lies outside them."""
    if v < lower:
        return v + TURN
    if v > upper:
        return v - TURN
    return v


@njit(cache=CACHE, nogil=True)
def angle_distance(a, b, periodic):  # pragma: no cover (compiled)
    """Joint distance [rad] of two rows, periodic joints at their nearest turn."""
    s = 0.0
    for c in range(a.shape[0]):
        v = a[c] - b[c]
        if periodic[c]:
            v -= TURN * np.rint(v * PER_TURN)
        s += v * v
    return math.sqrt(s)


@njit(cache=CACHE, nogil=True)
def turned_into(x, lower, upper, out):  # pragma: no cover (compiled)
    """``x`` with every angle turned by whole turns into its limits, into ``out``.

    Returns whether every joint fits (a joint whose range spans a turn always does).
    """
    ok = True
    for c in range(x.shape[0]):
        v = lower[c] + (x[c] - lower[c]) % TURN
        if v > upper[c] + LIMIT_SLACK:
            ok = False
        out[c] = min(v, upper[c])
    return ok


@njit('boolean[::1](float64[:, ::1], float64[::1], float64[::1], float64[:, ::1])', cache=CACHE,
      nogil=True)
def turned_rows(q, lower, upper, out):  # pragma: no cover (compiled)
    """Each row of ``q`` turned into the limits (:func:`turned_into`) into ``out``; which fit."""
    fits = np.empty(q.shape[0], dtype=np.bool_)
    for i in range(q.shape[0]):
        fits[i] = turned_into(q[i], lower, upper, out[i])
    return fits


@njit(cache=CACHE, nogil=True)
def flip_triple(x, a):  # pragma: no cover (compiled)
    """Joints ``a, a+1, a+2`` of ``x`` flipped in place (a spherical triple's other way).

    The first and third turned by half a turn, the middle one mirrored
    (:func:`~sik_ros.kinematics.branches.exact_flips`).
    """
    x[a] += math.pi
    x[a + 1] = -x[a + 1]
    x[a + 2] += math.pi


@njit('void(float64[:, ::1], int64)', cache=CACHE, nogil=True)
def flip_rows(q, a):  # pragma: no cover (compiled)
    """Every row of ``q`` flipped at joint ``a`` in place (:func:`flip_triple`)."""
    for i in range(q.shape[0]):
        flip_triple(q[i], a)
