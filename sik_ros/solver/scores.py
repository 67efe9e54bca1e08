"""Scores and distinct postures: how far candidates are from a goal, and which are apart.

One score orders candidates everywhere (:func:`pose_score`: the position error plus the
orientation error weighted by :data:`~sik_ros.solver.config.ORIENTATION_WEIGHT`); a candidate
is exact when it meets the tolerances (:func:`converged`); rows are kept greedily at least a
threshold apart (:func:`distinct_mask`). The ranking of an answer over these is
:mod:`sik_ros.solver.ranking`.
"""

from typing import Optional

import numpy as np

from sik_ros.kernels import as_arg
from sik_ros.kernels.sets import distinct_rows, NO_GROUPS
from sik_ros.solver.batch import Candidates
from sik_ros.solver.config import ORIENTATION_WEIGHT, SolverConfig
from sik_ros.solver.context import POSITION


def pose_score(perr: np.ndarray, oerr: np.ndarray) -> np.ndarray:
    """How far candidates are from the goal [m]: position error + weighted orientation error."""
    return perr + ORIENTATION_WEIGHT * oerr


def converged(perr: np.ndarray, oerr: np.ndarray, kind: str, cfg: SolverConfig) -> np.ndarray:
    """Whether each candidate meets the tolerances of a ``kind`` goal, (M,) bool."""
    ok = perr <= cfg.position_tolerance
    if kind != POSITION:
        ok &= oerr <= cfg.orientation_tolerance
    return ok


def assess(q: np.ndarray, z: np.ndarray, perr: np.ndarray, oerr: np.ndarray, kind: str,
           cfg: SolverConfig) -> Candidates:
    """A :class:`Candidates` batch with its ``exact`` flags computed."""
    return Candidates(q, z, perr, oerr, converged(perr, oerr, kind, cfg))


def distinct_mask(q: np.ndarray, threshold: float, ignore_last: bool = False,
                  periodic: Optional[np.ndarray] = None,
                  groups: Optional[np.ndarray] = None) -> np.ndarray:
    """Greedy keep-mask of rows (in their order) at least ``threshold`` apart [rad].

    With ``ignore_last`` the last joint is left out of the distance (for position goals, when
    it only turns the tool about its own axis: :meth:`Context.ignores_last`). With
    ``periodic`` (n,) bool, those joints' differences are taken at their nearest 2 pi turns:
    rows apart however turned. With ``groups`` (M,) int, rows of two posture families (two
    groups >= 0) are kept however near: two solutions no motion within the limits joins.
    """
    if len(q) < 2:
        return np.ones(len(q), dtype=bool)
    n = q.shape[1]
    turns = np.zeros(n, dtype=bool) if periodic is None else as_arg(periodic, bool)
    return distinct_rows(as_arg(q), float(threshold), n - 1 if ignore_last else n, turns,
                         NO_GROUPS if groups is None else as_arg(groups, np.int64))


def by_score(c: Candidates) -> Candidates:
    """Exact candidates first, then by score."""
    return c.take(np.lexsort((pose_score(c.perr, c.oerr), ~c.exact)))


def best_distinct(c: Candidates, threshold: float, ignore_last: bool) -> Candidates:
    """Exact candidates first, then by score; one per distinct posture."""
    c = by_score(c)
    return c.take(distinct_mask(c.q, threshold, ignore_last))
