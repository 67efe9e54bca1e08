"""The ranking of candidates into solutions, and distinct postures by the solver's own rule.

Candidates are scored by :mod:`sik_ros.solver.scores` (:func:`pose_score`: the position
error plus the weighted orientation error). Ranking is lexicographic, whatever
the scale of the objective (:func:`ranked_order`): the tier first (free and exact, free and
inexact, colliding; :func:`sik_ros.solver.results.tiers`), then, within a tier, exact before
inexact, the families not yet ranked before further solutions of those that are, a posture
before a second 2 pi equivalent of it, and the cost: the objective for exact solutions, the
weighted goal error for inexact ones.
"""

from typing import List, Optional, Sequence

import numpy as np

from sik_ros.deadline import Deadline, NO_DEADLINE
from sik_ros.kinematics.collision import Obstacle
from sik_ros.kinematics.periodic import posture_keys
from sik_ros.solver.batch import Candidates
from sik_ros.solver.config import INEXACT_COST
from sik_ros.solver.context import Context
from sik_ros.solver.families.membership import rounds, same_solution
from sik_ros.solver.objectives import JointLimitMargin, Objective, SeedDistance
from sik_ros.solver.results import Solution, tiers
from sik_ros.solver.scores import best_distinct, distinct_mask, pose_score


def posture_mask(ctx: Context, q: np.ndarray, kind: str,
                 threshold: Optional[float] = None) -> np.ndarray:
    """Greedy keep-mask of a ``kind`` goal's configurations (M, n) of distinct postures.

    Rows at least ``threshold`` [rad] apart (default: the solver's own rule,
    :func:`~sik_ros.solver.families.same_solution`: ``config.distinct_threshold``, or one
    branch's reach for the isolated solutions of a pose of an arm of six joints or fewer), the
    last joint left out where it only turns the tool (:meth:`Context.ignores_last`).
    """
    return distinct_mask(q, same_solution(ctx, kind) if threshold is None else threshold,
                         ctx.ignores_last(kind))


def equivalents(keys: np.ndarray, cost: np.ndarray) -> np.ndarray:
    """(M,) bool: rows that are 2 pi equivalents of a row of lower ``cost`` (same posture).

    ``keys``: the rows' :func:`posture_keys`.
    """
    if len(keys) < 2:
        return np.zeros(len(keys), dtype=bool)
    order = np.argsort(cost, kind='stable')
    # equal keys side by side, in cost order within each run (a stable sort on the columns,
    # cheaper than np.unique(axis=0))
    by_key = np.lexsort(keys[order].T[::-1])
    ranked = keys[order][by_key]
    first = np.ones(len(keys), dtype=bool)
    first[1:] = (ranked[1:] != ranked[:-1]).any(axis=1)
    out = np.ones(len(keys), dtype=bool)
    out[order[by_key[first]]] = False  # the cheapest row of each posture
    return out


def ranked_order(tier: np.ndarray, inexact: np.ndarray, repeat: np.ndarray,
                 equivalent: np.ndarray, cost: np.ndarray) -> np.ndarray:
    """The rows (M,) in ranking order: the one rule every ranked answer follows.

    Lexicographic: ``tier`` (:func:`~sik_ros.solver.results.tiers`), exact before
    ``inexact``, the ``repeat`` round within the row's family (0: the family's first; rows
    without a family are 0), a posture before its 2 pi ``equivalent`` s, then ``cost``.
    """
    return np.lexsort((cost, equivalent, repeat, inexact, tier))


#: Times the ranking orders its candidates again after self-collisions moved a family's first
#: (and so its rounds), checking the rows brought forward.
RECHECKS = 3


def rank(ctx: Context, c: Candidates, q_seed: Optional[np.ndarray],
         obstacles: Sequence[Obstacle], objective: Optional[Objective],
         limit: Optional[int] = None, deadline: Deadline = NO_DEADLINE,
         self_collision: Optional[np.ndarray] = None,
         families: Optional[np.ndarray] = None,
         every_family: bool = False) -> List[Solution]:
    """Solutions ranked best first; with ``limit``, only the best ``limit`` of them.

    The order is lexicographic (:func:`ranked_order`, the one place it is decided): tier (free
    and exact, free and inexact, colliding or self-colliding), then exact before inexact, then,
    with ``families``, a family's best before further solutions of families already ranked,
    then a posture before its further 2 pi equivalents (periodic joints; the best of each by
    the objective ranks with the others), then the cost within the tier, which each solution
    reports as its ``score``: the objective for exact solutions, :func:`pose_score` times
    :data:`INEXACT_COST` for inexact ones. Neither an objective value, however large, nor a
    family lifts a solution across a tier. The default objective is the distance to the seed
    when there is one, else the closeness to the joint limits. Self-collision is checked
    lazily in ranking order, so checking stops once ``limit`` free postures are found. Past
    ``deadline`` no more collision checks start: clearances not computed are NaN and rank as
    colliding; self-collision not checked is reported False. ``self_collision`` (M,) bool: the
    candidates' self-collision when already checked. ``families`` (M,) int: the candidates'
    family roots (-1: none, :func:`sik_ros.solver.families.roots`); each solution's ``family``
    is its root (numbered later by :func:`sik_ros.solver.families.number`). With
    ``every_family`` (every family of the pose known, as an analytic solver gives them: the
    branches of an arm of six joints or fewer, the search's pieces of a 7-joint arm's
    self-motion) the answer holds every family's first, whatever its tier, before further
    solutions (a family that touches the arm itself is in the answer, as an analytic solver's
    would hold it, ranked after the free ones); with the default ranking (no seed, no
    objective) a family's later solutions come in rounds within their tier
    (:func:`sik_ros.solver.families.rounds`): a second of each family, the one farthest from
    its first, before any third, and so on, so the answers spread over every family rather
    than gather where the cost is least. A family's first is
    its best row by tier, so self-collisions can move it (and its rounds): the rows the new
    order brings forward are checked too (:data:`RECHECKS` times at most).
    """
    if len(c) == 0:
        return []
    clear = ctx.checker.clearance(c.q, obstacles, deadline)
    hit = (clear <= 0.0) | np.isnan(clear)
    # the default ranking of a pose whose every family is known spreads a family's answers
    spread = every_family and objective is None and q_seed is None
    if objective is None:
        objective = SeedDistance(q_seed) if q_seed is not None else JointLimitMargin(ctx.robot)
    cost = np.asarray(objective(c.q), dtype=float)
    within = np.where(c.exact, cost, pose_score(c.perr, c.oerr) * INEXACT_COST)
    inexact = ~c.exact
    equivalent = np.zeros(len(c), dtype=bool)
    if ctx.robot.periodic.any():
        keys = posture_keys(c.q, ctx.robot.periodic)
        # the cheapest of each posture by (exact first, cost): its position in that order
        position = np.empty(len(c))
        position[np.lexsort((within, inexact))] = np.arange(len(c))
        equivalent = equivalents(keys, position)
    else:
        keys = None

    periodic = ctx.robot.periodic
    repeat = np.zeros(len(c), dtype=np.int64)  # each row's round in its family (or a second)
    if families is not None:
        repeat = rounds(families, np.lexsort((within, equivalent, inexact, hit)), c.q, periodic,
                        spread)

    def order(colliding: np.ndarray) -> np.ndarray:
        tier = tiers(colliding, inexact)
        if every_family:  # the rows chosen: every family's first, whatever its tier
            return np.lexsort((within, equivalent, repeat, tier, repeat > 0, inexact))
        return ranked_order(tier, inexact, repeat, equivalent, within)

    limit = len(c) if limit is None else limit
    checked: dict = {}
    selfc = self_collisions(ctx, c, order(hit), keys, limit, self_collision, deadline, checked)
    colliding = hit | selfc
    for _ in range(RECHECKS):
        if families is None or not selfc.any():
            break
        # a family's first is its best free one, and its rounds follow from it: the rows the
        # new order brings forward are checked too
        repeat[:] = rounds(families, np.lexsort((within, equivalent, inexact, colliding)),
                           c.q, periodic, spread)
        more = selfc | self_collisions(ctx, c, order(colliding), keys, limit, self_collision,
                                       deadline, checked)
        if (more == selfc).all():
            break
        selfc = more
        colliding = hit | selfc
    tier = tiers(colliding, inexact)
    family = np.full(len(c), -1, dtype=np.int64) if families is None else families
    rows = order(colliding)[:limit]
    if every_family:  # the rows chosen, in ranking order
        place = np.empty(len(c), dtype=np.int64)
        place[ranked_order(tier, inexact, repeat, equivalent, within)] = np.arange(len(c))
        rows = rows[np.argsort(place[rows])]
    # the rows kept taken at once (each solution's arrays a row of its own), their fields as
    # Python values (not one NumPy scalar at a time)
    q, z = c.q[rows], c.z[rows].astype(np.float32)
    fields = zip(c.perr[rows].tolist(), c.oerr[rows].tolist(), within[rows].tolist(),
                 clear[rows].tolist(), selfc[rows].tolist(), c.exact[rows].tolist(),
                 tier[rows].tolist(), np.asarray(family)[rows].tolist())
    return [Solution(q=qk, position_error=pe, orientation_error=oe, posture_index=zk,
                     score=score, min_obstacle_distance=cl, self_collision=sc, converged=ex,
                     tier=t, family=f)
            for qk, zk, (pe, oe, score, cl, sc, ex, t, f) in zip(q, z, fields)]


def self_collisions(ctx: Context, c: Candidates, rows: np.ndarray, keys: Optional[np.ndarray],
                    limit: int, known: Optional[np.ndarray], deadline: Deadline,
                    checked: Optional[dict] = None) -> np.ndarray:
    """(M,) bool: self-collision of ``c``'s rows checked in the order ``rows`` (False: not).

    Checking stops once ``limit`` rows are free or past ``deadline``. 2 pi equivalents (equal
    ``keys``) place the arm alike: one check per posture. The checks go in batches of the
    rows still needed (each row frees at most one), one checker call per batch. ``known``:
    the self-collision of each row when already checked; ``checked``: the postures an earlier
    call checked (by key), added to.
    """
    selfc = np.zeros(len(c), dtype=bool)
    checked = {} if checked is None else checked
    free = start = 0
    while start < len(rows) and free < limit and not deadline.expired():
        batch = rows[start:start + limit - free]
        start += len(batch)
        batch_keys = [int(i) if keys is None else keys[i].tobytes() for i in batch]
        if known is not None:
            checked.update(zip(batch_keys, known[batch].tolist()))
        else:
            new = {}
            for i, key in zip(batch, batch_keys):
                if key not in checked:
                    new.setdefault(key, i)
            hits = ctx.checker.self_collision(c.q[list(new.values())], deadline)
            checked.update(zip(new, hits.tolist()))
        for i, key in zip(batch, batch_keys):
            if key not in checked:  # past the deadline: not checked
                return selfc
            selfc[i] = checked[key]
            free += not selfc[i]
    return selfc


def from_solutions(sols: Sequence[Solution]) -> Candidates:
    """The candidates that ranked solutions came from."""
    return Candidates(np.array([s.q for s in sols]), np.array([s.posture_index for s in sols]),
                      np.array([s.position_error for s in sols]),
                      np.array([s.orientation_error for s in sols]),
                      np.array([s.converged for s in sols], dtype=bool))


def merge(ctx: Context, sols: Sequence[Solution], extra: Sequence[Solution], kind: str,
          q_seed: Optional[np.ndarray], obstacles: Sequence[Obstacle],
          objective: Optional[Objective], deadline: Deadline = NO_DEADLINE) -> List[Solution]:
    """Two lists of solutions ranked together, one per distinct posture."""
    c = best_distinct(from_solutions(list(sols) + list(extra)), ctx.config.distinct_threshold,
                      ctx.ignores_last(kind))
    return rank(ctx, c, q_seed, obstacles, objective, deadline=deadline)
