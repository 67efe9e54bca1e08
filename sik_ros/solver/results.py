"""What a solve returns: ranked :class:`Solution` s in an :class:`IKResult`, and its JSON view."""

from dataclasses import dataclass, field
import json
import threading
from typing import Callable, Dict, List, Optional, Sequence

import numpy as np

#: Ranking tiers (:attr:`Solution.tier`), best first: free of collisions and within the
#: tolerances; free and outside them; touching an obstacle or the robot itself.
FREE_EXACT, FREE_INEXACT, COLLIDING = 0, 1, 2
#: :attr:`Solution.family` of a solution on no family: not exact (a best-effort answer).
NO_FAMILY = 65535


def tiers(colliding: np.ndarray, inexact: np.ndarray) -> np.ndarray:
    """(M,) int64: each candidate's ranking tier from its collision and inexact flags (M,)."""
    return np.where(colliding, COLLIDING, np.where(inexact, FREE_INEXACT, FREE_EXACT))


def tier_label(tier: int, self_collision: bool = False) -> str:
    """A short name of a ranking tier for tables: free, inexact, obstacle or self-coll."""
    if tier == COLLIDING:
        return 'self-coll.' if self_collision else 'obstacle'
    return {FREE_EXACT: 'free', FREE_INEXACT: 'inexact'}.get(tier, f'tier {tier}')


def family_label(solution: 'Solution') -> str:
    """A solution's family for tables: its number, or '-' when it has none (inexact)."""
    return '-' if solution.family == NO_FAMILY else str(solution.family)


@dataclass
class Solution:
    """One joint solution.

    Attributes:
        q: joint positions (n,) [rad], within the limits.
        position_error: distance from the tip to the target [m].
        orientation_error: angle between tip and target orientation [rad] (0 for position goals).
        posture_index: the posture index that produced it; for a solution refined from a
            start without one (the seed, another model's posture, a restart), its encoding,
            computed on first read (:class:`PendingIndices`).
        score: the ranking cost within its tier, lower is better: the objective for exact
            solutions, the weighted goal error for inexact ones (see ``tier``).
        min_obstacle_distance: clearance from the obstacles [m] (+inf without obstacles).
        self_collision: whether the posture collides with itself.
        converged: whether it meets the tolerances.
        tier: the ranking tier, ranked first: 0 free of collisions and exact, 1 free and
            inexact, 2 touching an obstacle or itself (:mod:`sik_ros.solver.ranking`).
        family: the posture family it belongs to, numbered within one answer by first
            appearance (0: the best-ranked solution's): a branch of an arm with six joints or
            fewer at a pose, a connected piece of self-motion of a redundant arm
            (:mod:`sik_ros.solver.families.membership`); :data:`NO_FAMILY` for an inexact solution.
    """

    q: np.ndarray
    position_error: float
    orientation_error: float
    posture_index: np.ndarray
    score: float = 0.0
    min_obstacle_distance: float = float('inf')
    self_collision: bool = False
    converged: bool = False
    tier: int = 0
    family: int = NO_FAMILY
    _pending: Optional['PendingIndices'] = field(default=None, init=False, repr=False,
                                                 compare=False)

    def __getstate__(self) -> dict:
        """The fields with the posture index computed (for pickling and copies)."""
        if self._pending is not None:
            self._pending.resolve()
        return dict(self.__dict__, _pending=None)

    @property
    def in_collision(self) -> bool:
        """Whether it touches an obstacle or itself."""
        return self.self_collision or not self.min_obstacle_distance > 0.0  # NaN: unknown


def _index_get(self: Solution) -> np.ndarray:
    pending = self.__dict__.get('_pending')
    if pending is not None:
        pending.resolve()
    return self.__dict__['_posture_index']


def _index_set(self: Solution, value: np.ndarray) -> None:
    self.__dict__['_posture_index'] = value


# a property over the dataclass field: its __init__ stores through the setter
Solution.posture_index = property(_index_get, _index_set, doc='The posture index (latent,).')


class PendingIndices:
    """The posture indices of some solutions, encoded together when one is first read.

    A caller asking for one solution seldom reads its index, and encoding it cost about as
    much as refining it; the service reads them all, in one encoder call.
    """

    def __init__(self, solutions: Sequence[Solution],
                 encode: Callable[[np.ndarray], np.ndarray]):
        self._solutions, self._encode = list(solutions), encode
        self._lock = threading.Lock()
        for s in self._solutions:
            s._pending = self

    def resolve(self) -> None:
        """Encode the solutions' configurations and store their indices (once)."""
        with self._lock:
            if self._encode is None:
                return
            z = self._encode(np.array([s.q for s in self._solutions]))
            for s, zi in zip(self._solutions, z):
                s.__dict__['_posture_index'] = zi.astype(np.float32)
                s._pending = None
            self._encode = None


@dataclass
class IKResult:
    """The answer to one target: ranked solutions, best first.

    Attributes:
        success: at least one solution is exact.
        solutions: the ranked solutions, best first.
        goal: ``'position'`` or ``'pose'``.
        timed_out: the deadline cut the search short.
        elapsed: the call's wall time [s].
        message: why there is no exact solution ('' when there is).
        num_families: how many posture families the goal has as far as the solver found
            (those of the solutions returned, and any others among the exact solutions found;
            0 without an exact solution).
    """

    success: bool
    solutions: List[Solution] = field(default_factory=list)
    goal: str = 'position'
    timed_out: bool = False
    elapsed: float = 0.0
    message: str = ''
    num_families: int = 0


def result_to_dict(res: IKResult, joint_names: Sequence[str]) -> Dict:
    """A JSON-ready view of a result (for ``sik-solve --json``)."""
    return {
        'success': res.success, 'goal': res.goal, 'timed_out': res.timed_out,
        'elapsed_s': res.elapsed, 'message': res.message, 'joint_names': list(joint_names),
        'num_families': res.num_families,
        'solutions': [{
            'q': s.q.tolist(), 'position_error': s.position_error,
            'orientation_error': s.orientation_error,
            'posture_index': [float(v) for v in s.posture_index], 'score': s.score,
            'min_obstacle_distance': (None if not np.isfinite(s.min_obstacle_distance)
                                      else s.min_obstacle_distance),
            'self_collision': s.self_collision, 'converged': s.converged, 'tier': s.tier,
            'family': None if s.family == NO_FAMILY else s.family,
        } for s in res.solutions],
    }


def dumps(res: IKResult, joint_names: Sequence[str]) -> str:
    """:func:`result_to_dict` as a JSON string."""
    return json.dumps(result_to_dict(res, joint_names), indent=2)
