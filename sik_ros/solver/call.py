"""One solve's request and what follows from it: its route and its early stop, decided once.

:func:`make_call` turns a checked request into a :class:`Call` that every stage of
:mod:`sik_ros.solver.pipeline` reads: whether the goal is out of reach or isolated, the seed
table that gives its starts, which route it takes (:data:`LEAN`, :data:`REFINED` or
:data:`RAW`, after the single-solution route where that applies) and after how many distinct
exact solutions refinement stops (``enough``). No stage decides them again.
"""

from dataclasses import dataclass, replace
from typing import Optional, Sequence

import numpy as np

from sik_ros.deadline import Deadline
from sik_ros.kinematics.collision import Obstacle
from sik_ros.solver.config import SolverConfig
from sik_ros.solver.context import Context, Goal, POSE
from sik_ros.solver.families.search import searchable
from sik_ros.solver.objectives import Objective
from sik_ros.tables.seed_table import SeedTable

#: The routes of a call: every branch of an isolated pose goal from the seed table's starts
#: in a few compiled calls (:mod:`sik_ros.solver.families.isolated`); the general stages with
#: refinement; the decoder's raw answers (``refine=False``).
LEAN, REFINED, RAW = 'lean', 'refined', 'raw'


@dataclass(frozen=True)
class Call:
    """One solve's request and what follows from it, handed to its stages.

    Attributes:
        goal, num, q_seed, obstacles, refined, objective, deadline, first_found: as
            :func:`~sik_ros.solver.pipeline.solve` takes them.
        one: one solution with the default ranking: the single-solution route
            (:mod:`sik_ros.solver.single`) first, the ``route`` below when it finds none.
        single: ``one``, from a seed (the seed refined first).
        far: the goal is farther than ``reach_margin`` from every table cell (out of reach).
        seeds: the seed table giving isolated pose solutions their starts, or None.
        isolated: a reachable, refined pose goal of an arm with six joints or fewer.
        search: the family search follows the self-motion of the solutions found (a
            reachable, refined pose goal of a 7-joint arm asking for several solutions, not
            a path's starts: :mod:`sik_ros.solver.families.search`).
        search_seeds: the seed table giving the search's call starts of its own, or None.
        one_per_family: at most one solution per posture family.
        route: :data:`LEAN`, :data:`REFINED` or :data:`RAW`.
        enough: distinct exact solutions after which refinement stops, or None (every start
            refined: every branch of an isolated goal, or a ranking that needs them all).
    """

    goal: Goal
    num: int
    q_seed: Optional[np.ndarray]
    obstacles: Sequence[Obstacle]
    refined: bool
    objective: Optional[Objective]
    deadline: Deadline
    first_found: bool
    one: bool
    single: bool
    far: bool
    seeds: Optional[SeedTable]
    isolated: bool
    search: bool
    search_seeds: Optional[SeedTable]
    one_per_family: bool
    route: str
    enough: Optional[int]


def spare(cfg: SolverConfig, num: int) -> int:
    """Distinct exact solutions found beyond the ``num`` asked for before the search stops.

    ``early_stop_margin``, at most ``num - 1``: a single solution is the first exact one
    found (as TRAC-IK's first answer); with the default margin of 2, two are the better two
    of three. Only for the default ranking (no seed, obstacles or objective).
    """
    return min(cfg.early_stop_margin, num - 1)


def make_call(ctx: Context, goal: Goal, num: int, q_seed: Optional[np.ndarray],
              obstacles: Sequence[Obstacle], refined: bool, objective: Optional[Objective],
              deadline: Deadline, first_found: bool = False,
              one_per_family: Optional[bool] = None) -> Call:
    """The :class:`Call` of a request: reach, isolation, seeds, route and early stop."""
    cfg = ctx.config
    # one solution with the default ranking: the seed refined first (single.py)
    one = num == 1 and refined and objective is None and not first_found
    single = one and q_seed is not None
    # a goal far from every position in the data is out of reach: answer quickly
    far = not ctx.models[goal.kind].table.within(goal.position, cfg.reach_margin)
    # isolated solutions (a pose, six joints or fewer): no self-motion to walk along, each
    # branch needs a start of its own, from the seed table near the goal pose when the bundle
    # has one, else drawn at random
    isolated = goal.kind == POSE and not far and ctx.robot.dof <= 6 and refined
    seeds = ctx.models[goal.kind].seeds if isolated and cfg.seed_starts > 0 else None
    # the family search traces the curves through the solutions found; the seed table's
    # starts reach curves that no model posture leads to
    search = num > 1 and refined and not far and not first_found and searchable(ctx, goal)
    search_seeds = ctx.models[goal.kind].seeds if search and cfg.family_seed_starts > 0 \
        else None
    per_family = cfg.one_per_family if one_per_family is None else one_per_family
    # ranked by the default objective, the first distinct exact solutions found are as good
    # as any: refinement stops once there are enough (with ``first_found`` also with a seed,
    # the few found then ranked by it); every branch of an isolated goal unless one is asked
    enough = None
    if not ((q_seed is not None and not first_found and not single) or obstacles or
            objective is not None or cfg.early_stop_margin < 0):
        enough = num + (0 if first_found else spare(cfg, num))
    if isolated and (seeds is not None or cfg.branch_restarts > 0) and num != 1:
        enough = None
    call = Call(goal=goal, num=num, q_seed=q_seed, obstacles=obstacles, refined=refined,
                objective=objective, deadline=deadline, first_found=first_found, one=one,
                single=single, far=far, seeds=seeds, isolated=isolated, search=search,
                search_seeds=search_seeds, one_per_family=per_family, route=RAW,
                enough=enough)
    return replace(call, route=RAW if not refined else LEAN if lean(call) else REFINED)


def lean(call: Call) -> bool:
    """Whether a call takes :mod:`sik_ros.solver.families.isolated`'s lean path.

    Isolated pose solutions with the seed table's starts, ranked by the default objective:
    no seed, obstacles or objective, and not a path's starts.
    """
    return call.seeds is not None and call.q_seed is None and not call.obstacles and \
        call.objective is None and not call.first_found
