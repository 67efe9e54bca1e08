"""Periodic joints: revolute joints whose range spans a whole turn (2 pi) or more.

Such a joint at ``q`` and at ``q +- 2 pi`` places the arm alike. This module holds what follows
from that, for the solver, the seed table and the compiled kernels alike: which joints are
periodic, the turn of a value nearest a target, a value brought back within its limits by a
turn, the equivalents of configurations within the limits, and keys equal for equivalent
configurations.
"""

import functools
from typing import Tuple

import numpy as np

from sik_ros.kernels.angles import LIMIT_SLACK, TURN

#: A joint whose range falls short of a turn by less than this counts as periodic [rad]
#: (ranges written with rounded values of pi).
RANGE_SLACK = 1e-6


def periodic_joints(lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """(n,) bool: the joints whose range [rad] spans a turn."""
    return upper - lower >= TURN - RANGE_SLACK


def within(q: np.ndarray, lower, upper) -> np.ndarray:
    """Where values fit their limits, up to :data:`LIMIT_SLACK` (elementwise bool)."""
    return (q >= lower - LIMIT_SLACK) & (q <= upper + LIMIT_SLACK)


def nearest_turns(robot, q: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``q`` (M, n) with periodic joints turned by whole turns to their values nearest ``target``.

    Each periodic joint of ``robot`` (its ``periodic``, ``lower`` and ``upper``) takes, of its
    equivalents within the limits, the one nearest ``target`` (n,): the same placements of
    the arm.
    """
    periodic = robot.periodic
    if not periodic.any() or len(q) == 0:
        return q
    lo, hi = robot.lower[periodic], robot.upper[periodic]
    v = q[:, periodic]
    chosen = v + TURN * np.round((target[periodic] - v) / TURN)
    # the turn nearest the target nearly always fits (a whole turn or more of range around a
    # target inside it); else the nearest of the turns either side that does, or none
    if not within(chosen, lo, hi).all():
        options = chosen[None] + TURN * np.array([0.0, -1.0, 1.0])[:, None, None]
        fits = within(options, lo, hi)                                          # (3, M, p)
        gap = np.where(fits, np.abs(options - target[periodic]), np.inf)
        best = np.take_along_axis(options, np.argmin(gap, axis=0)[None], axis=0)[0]
        chosen = np.where(np.isfinite(gap.min(axis=0)), best, v)
    out = q.copy()
    out[:, periodic] = chosen
    return out


def equivalents(robot, q: np.ndarray, turnable: Tuple[bool, ...],
                per_row: int) -> Tuple[np.ndarray, np.ndarray]:
    """Each row of ``q`` (M, n) and after it its equivalents within ``robot``'s limits.

    The ``turnable`` joints (periodic ones a caller lets turn) turned by +-2 pi: one joint,
    then two; at most ``per_row`` equivalents per row.

    Returns:
        the source row of each output row, and the output rows (clipped onto the limits).
    """
    patterns = turn_patterns(turnable)
    if len(patterns) == 0 or len(q) == 0:
        return np.arange(len(q)), q
    lower, upper = robot.lower, robot.upper
    turned = q[:, None, :] + patterns[None]                                  # (M, P, n)
    fits = np.all(within(turned, lower, upper), axis=2)
    fits &= np.cumsum(fits, axis=1) <= per_row                          # the first ones per row
    rows, cols = np.nonzero(np.concatenate([np.ones((len(q), 1), bool), fits], axis=1))
    shifted = np.concatenate([q[:, None], turned], axis=1)[rows, cols]
    return rows, np.clip(shifted, lower, upper)


@functools.lru_cache(maxsize=16)
def turn_patterns(turnable: Tuple[bool, ...]) -> np.ndarray:
    """Shifts (P, n) [rad] that turn one, then two, of the ``turnable`` joints by +-2 pi."""
    turns = np.flatnonzero(turnable)
    out = []
    for j in turns:
        for s in (TURN, -TURN):
            v = np.zeros(len(turnable))
            v[j] = s
            out.append(v)
    for a in range(len(turns)):
        for b in range(a + 1, len(turns)):
            for sa in (TURN, -TURN):
                for sb in (TURN, -TURN):
                    v = np.zeros(len(turnable))
                    v[turns[a]], v[turns[b]] = sa, sb
                    out.append(v)
    return np.array(out).reshape(-1, len(turnable))


def posture_keys(q: np.ndarray, periodic: np.ndarray) -> np.ndarray:
    """(M, n) int64: equal rows for configurations that are exact 2 pi shifts of each other."""
    wrapped = q.copy()
    wrapped[:, periodic] = np.mod(q[:, periodic] + np.pi, TURN)
    return np.round(wrapped * 1e6).astype(np.int64)
