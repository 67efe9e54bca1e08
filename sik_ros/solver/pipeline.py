"""One solve, stage by stage.

0. one solution (default ranking): the seed refined first, then the oriented postures of a
   redundant arm's pose goal (:mod:`sik_ros.solver.single`); the stages below only when that
   gives no exact, free solution;
1. candidates: the table's indices near the goal (the seed's own first) and, for pose goals,
   the position model's postures that had the goal's orientation;
2. their postures (the table's decoded postures, or a decode at the goal; raw answers are
   always decoded at the goal, for pose goals at indices Algorithm 2 adjusted towards it);
3. refinement, then restarts when nothing converged, then for pose goals the self-motion walk
   (arms with more than six joints); for six joints or fewer the other branches' starts join
   the first refinement (the seed table's configurations near the goal pose, or random ones);
4. exact solutions first, one per distinct posture, with the 2 pi equivalents of periodic
   joints, ranked (collisions, objective); when every exact one collides with the arm itself
   (goals close to the base), restarts for free ones (not after the seed table's starts);
5. Algorithm 2 when obstacles leave no free exact solution.
"""

import math
from typing import List, Optional, Sequence, Tuple

import numpy as np

from sik_ros.deadline import Deadline
from sik_ros.kinematics.collision import Obstacle
from sik_ros.kinematics.periodic import nearest_turns
from sik_ros.solver import families
from sik_ros.solver.adjust import adjust_index, adjust_raw
from sik_ros.solver.batch import Candidates
from sik_ros.solver.call import Call, LEAN, make_call, REFINED, spare
from sik_ros.solver.candidates import (oriented_postures, own_index, starting_postures,
                                       table_candidates)
from sik_ros.solver.codec import decode
from sik_ros.solver.config import FAR_ITERATIONS, FREE_RESTARTS, FREE_ROUNDS, START_MERGE
from sik_ros.solver.context import Context, Goal, POSE, POSITION
from sik_ros.solver.explore import (branch_starts, periodic_equivalents, restart, seed_starts,
                                    unindexed, walk)
from sik_ros.solver.families.branches import other_branches, polished
from sik_ros.solver.families.isolated import every_branch
from sik_ros.solver.families.search import Atlas, search
from sik_ros.solver.objectives import Objective
from sik_ros.solver.ranking import from_solutions, merge, rank
from sik_ros.solver.refine import errors, refine
from sik_ros.solver.results import IKResult, Solution
from sik_ros.solver.scores import assess, by_score, distinct_mask, pose_score
from sik_ros.solver.single import (fill_indices, from_starts, oriented_count,
                                   single_starts, turns_centre)


def initial_postures(ctx: Context, goal: Goal, num: int, q_seed: Optional[np.ndarray],
                     refined: bool, seeded: bool = False) -> Candidates:
    """Stages 1 and 2: the starting postures and their indices (errors not yet known).

    Order: the seed itself, the seed's own posture (its index decoded), then the oriented ones
    (pose goals), then the table's. The seed and the oriented postures have no index of the
    goal's model yet: NaN, encoded once ranked. With ``seeded`` (isolated pose solutions whose
    starts come from the seed table) only the seed and its own posture: the oriented and
    table postures find no branch the seed table's starts miss (docs/design.md).
    """
    extra = oriented_postures(ctx, goal, oriented_count(ctx.config, num)) \
        if goal.kind == POSE and refined and not seeded else np.empty((0, ctx.robot.dof))
    z, rows = own_index(ctx, goal, q_seed) if seeded else \
        table_candidates(ctx, goal, q_seed, num, refined, len(extra))
    q = starting_postures(ctx, goal, z, rows) if refined else decode(ctx, goal, z)
    if len(extra):
        head = 1 if q_seed is not None else 0
        q = np.concatenate([q[:head], extra, q[head:]])
        z = np.concatenate([z[:head], np.full((len(extra), z.shape[1]), np.nan), z[head:]])
    if q_seed is not None and refined:
        # the current state itself: refined, it is the solution nearest to it
        q = np.concatenate([q_seed[None], q])
        z = np.concatenate([np.full((1, z.shape[1]), np.nan), z])
    unknown = np.full(len(q), np.inf)
    return Candidates(q, z, unknown, np.zeros(len(q)), np.zeros(len(q), dtype=bool))


def distinct_postures(ctx: Context, c: Candidates, goal: Goal,
                      q_seed: Optional[np.ndarray], atlas: Optional[Atlas] = None) -> Candidates:
    """Stage 4 before ranking: the exact candidates (all when none is), one per posture.

    With periodic joints each candidate first takes the 2 pi turns nearest the seed (or the
    middle of the joint ranges), a posture found at several turns (from different starts)
    is kept once, nearest the seed, and its equivalents within the limits are added. With the
    search's ``atlas``, solutions on two of its pieces (two families) are never one, however
    near: a small family beside a large one, parted by a joint limit, keeps its solutions.
    """
    cfg = ctx.config
    threshold = cfg.distinct_threshold
    if c.exact.any():  # with exact solutions, only exact ones are returned
        c = c.take(c.exact)
        # isolated solutions: one per branch (two branches are never merged as near)
        threshold = families.same_solution(ctx, goal.kind)
    ignore_last = ctx.ignores_last(goal.kind)
    periodic = ctx.robot.periodic
    if not periodic.any():
        c = by_score(c)
        return c.take(distinct_mask(c.q, threshold, ignore_last,
                                    groups=pieces(ctx, c, atlas)))
    centre = turns_centre(ctx, q_seed)
    q = nearest_turns(ctx.robot, c.q, centre)
    # exact ones nearest the seed first (of nearly one posture, the one kept), then by score
    near = np.linalg.norm(q - centre, axis=1)
    c = Candidates(q, c.z, c.perr, c.oerr, c.exact).take(
        np.lexsort((np.where(c.exact, near, pose_score(c.perr, c.oerr)), ~c.exact)))
    c = c.take(distinct_mask(c.q, threshold, ignore_last, periodic, pieces(ctx, c, atlas)))
    # postures apart however turned: so are their equivalents (a whole turn from each other
    # on some joint the distance counts: a last joint it leaves out is not turned), so they
    # need only their order (no pairwise check)
    return by_score(periodic_equivalents(ctx, c, ignore_last=ignore_last))


def pieces(ctx: Context, c: Candidates, atlas: Optional[Atlas]) -> Optional[np.ndarray]:
    """(M,) int64: the atlas piece of each exact row of ``c`` (-1: none), or None without one."""
    if atlas is None:
        return None
    out = atlas.pieces_of(c.q, ctx.robot.periodic)
    out[~c.exact] = -1
    return out


def seed_posture_first(ctx: Context, goal: Goal, own: Candidates, sols: List[Solution],
                       q_seed: np.ndarray, obstacles: Sequence[Obstacle], num: int,
                       deadline: Deadline) -> List[Solution]:
    """A seeded raw answer: the seed's own posture index decoded first (the posture kept).

    Raw answers are otherwise ranked by their error; the paper's use of the index of the
    current state is to keep its posture, so it leads unless it collides. The others follow,
    without those of nearly the same posture.
    """
    first = rank(ctx, own, q_seed, obstacles, None, limit=1, deadline=deadline)
    if not first or first[0].in_collision:
        return sols
    keep = ctx.ignores_last(goal.kind)
    cols = slice(0, ctx.robot.dof - 1) if keep else slice(None)
    rest = [s for s in sols if np.linalg.norm((s.q - first[0].q)[cols])
            >= ctx.config.distinct_threshold]
    return (first + rest)[:num]


def solve(ctx: Context, goal: Goal, num: int, q_seed: Optional[np.ndarray],
          obstacles: Sequence[Obstacle], refined: bool, objective: Optional[Objective],
          deadline: Deadline, first_found: bool = False,
          one_per_family: Optional[bool] = None) -> IKResult:
    """Ranked solutions for one checked goal (see the module's stages).

    ``one_per_family``: at most one solution per posture family (None: the config's
    ``one_per_family``). The route (:func:`~sik_ros.solver.call.make_call`) is chosen once.

    With ``first_found`` (a path's starts) refinement stops at the first ``num`` distinct
    exact solutions even with a seed (then ranked by it): the seed's own row may be left
    unfinished (a path's starts follow the seed onto the goal on their own). Their posture
    indices are left unknown (NaN) unless obstacles need them (Algorithm 2).
    """
    call = make_call(ctx, goal, num, q_seed, obstacles, refined, objective, deadline,
                     first_found, one_per_family)
    if call.one:
        # one solution: the seed refined alone first; when that fails, the first exact
        # solution of the other starts (the seed's own row and posture already tried), as
        # without a seed, ranked by the seed; then the route below
        starts = single_starts(ctx, goal, q_seed, obstacles)
        if starts is not None and len(starts):
            result = from_starts(ctx, goal, starts, q_seed, obstacles, deadline)
            if result is not None:
                return result
    timed_out = False
    own = atlas = None
    if call.route == LEAN:  # every branch, unless one is asked for
        result, c, timed_out = every_branch(ctx, goal, call.seeds, num, call.enough,
                                            deadline)
        if result is not None:
            return result
        c, timed_out, atlas = more_starts(ctx, call, c, timed_out)
    elif call.route == REFINED:
        c = initial_postures(ctx, goal, num, None if call.single else q_seed, refined,
                             seeded=call.seeds is not None)
        c, timed_out, atlas = refine_all(ctx, call, c)
    else:
        c = initial_postures(ctx, goal, num, q_seed, refined)
        c = assess(c.q, c.z, *errors(ctx, c.q, goal), goal.kind, ctx.config)
        if goal.kind == POSE:  # Algorithm 2 on the tip pose error: still decoded postures
            c = adjust_raw(ctx, goal, c, num, q_seed is not None, call.deadline)
        own = c.take(np.arange(1)) if q_seed is not None and objective is None else None
    c = distinct_postures(ctx, c, goal, q_seed, atlas)
    fam = family_roots(ctx, call, c, atlas)
    sols = rank(ctx, c, q_seed, obstacles, objective, limit=num, deadline=deadline,
                families=fam, every_family=every_family(call, atlas))
    if own is not None:
        sols = seed_posture_first(ctx, goal, own, sols, q_seed, obstacles, num, deadline)
    sols, fam, cut = free_rounds(ctx, call, c, sols, fam, atlas)
    return finish(ctx, call, sols, timed_out or cut, fam)


def every_family(call: Call, atlas: Optional[Atlas]) -> bool:
    """Whether the candidates hold every family of the pose, each to come before a second.

    The branches of an isolated pose goal, and the pieces of the search's atlas.
    """
    return call.isolated or atlas is not None


def family_roots(ctx: Context, call: Call, c: Candidates,
                 atlas: Optional[Atlas] = None) -> Optional[np.ndarray]:
    """The family root of each candidate (-1: not exact), or None when not labelled.

    A path's starts (``first_found``) are not ranked by family: their tracks are. A call
    asking for one solution answers one family (:func:`finish`) without linking candidates.
    With the search's ``atlas``, the families are its pieces.
    """
    if call.first_found or call.num == 1:
        return None
    return families.roots(ctx, c, call.goal, call.deadline, atlas)


def refine_all(ctx: Context, call: Call,
               c: Candidates) -> Tuple[Candidates, bool, Optional[Atlas]]:
    """Stage 3: the starts refined, then restarts, the search or the walk where they fall short.

    Returns:
        the refined candidates, whether the deadline cut refinement short, and the search's
        atlas (None without one).
    """
    cfg, goal, deadline = ctx.config, call.goal, call.deadline
    # decoded postures that nearly coincide would refine to the same solution
    c = c.take(distinct_mask(c.q, cfg.distinct_threshold * START_MERGE,
                             ctx.ignores_last(goal.kind)))
    if call.seeds is not None:
        c = Candidates.concat(c, seed_starts(ctx, goal, call.seeds, cfg.seed_starts,
                                             c.z.shape[1]))
    elif call.isolated and cfg.branch_restarts > 0:
        c = Candidates.concat(c, branch_starts(ctx, goal, cfg.branch_restarts, c.z.shape[1]))
    elif call.search_seeds is not None:  # starts on curves no model posture leads to
        c = Candidates.concat(c, seed_starts(ctx, goal, call.search_seeds,
                                             cfg.family_seed_starts, c.z.shape[1]))
    # starts from the seed table are far apart already: merging the few heading for one
    # solution saves less than it costs (docs/design.md, "Measured choices")
    r = refine(ctx, c.q, goal, deadline, FAR_ITERATIONS if call.far else None,
               prune=call.seeds is None, enough=call.enough)
    z = c.z
    if call.seeds is not None and call.enough is None:  # every branch: starts for those missed
        r = polished(ctx, goal, call.seeds.signs,
                     other_branches(ctx, goal, call.seeds, r, deadline))
        z = np.concatenate([z, unindexed(r.q[len(z):], z.shape[1])])
    c = assess(r.q, z, r.perr, r.oerr, goal.kind, cfg)
    return more_starts(ctx, call, c, r.cut_short)


def more_starts(ctx: Context, call: Call, c: Candidates,
                timed_out: bool) -> Tuple[Candidates, bool, Optional[Atlas]]:
    """Stage 3 after the first refinement ``c``: restarts, then the family search or the walk.

    A call asking for one solution that none of these made exact refines the seed table's
    starts last (:func:`seed_table_rescue`), as the search of a larger call would.

    The search (a 7-joint arm's pose goal asking for several solutions) traces every curve
    of the self-motion through the solutions found and gives points far apart on each of
    its pieces; other pose goals of redundant arms walk from the solutions found.

    Returns:
        the refined candidates, whether the deadline cut refinement short, and the search's
        atlas (None without one).
    """
    cfg, goal, num, deadline = ctx.config, call.goal, call.num, call.deadline
    if goal.kind == POSE and not call.far and not c.exact.any() and \
            not deadline.expired() and call.seeds is None and \
            oriented_count(cfg, num) < cfg.oriented_candidates:
        c, cut = more_oriented(ctx, call, c)
        timed_out = timed_out or cut
    if not call.far and not c.exact.any():
        c, cut = restart(ctx, c, goal, deadline)
        timed_out = timed_out or cut
    if call.one and not call.far and not c.exact.any() and not deadline.expired():
        c, cut = seed_table_rescue(ctx, call, c)
        timed_out = timed_out or cut
    atlas = None
    if call.search:
        c, atlas = search(ctx, c, goal, deadline)  # every piece of the curves found
    if atlas is None and goal.kind == POSE and not call.far and ctx.robot.dof > 6 and \
            cfg.walk_rounds > 0:
        # the first exact ones are as good as any only with the default ranking
        margin = spare(cfg, num) if call.enough is not None else cfg.early_stop_margin
        c = walk(ctx, c, goal, deadline, num + max(margin, 0))
    return c, timed_out, atlas


def seed_table_rescue(ctx: Context, call: Call, c: Candidates) -> Tuple[Candidates, bool]:
    """``c`` and the seed table's starts near the goal pose, refined: one solution's last try.

    A call asking for several solutions of a 7-joint arm's pose goal refines these starts in
    its search (``search_seeds``); one asking for one refines them only when nothing else
    gave an exact solution, so that it succeeds wherever the larger call does.
    """
    goal, cfg = call.goal, ctx.config
    seeds = ctx.models[goal.kind].seeds
    if goal.kind != POSE or seeds is None or cfg.family_seed_starts <= 0:
        return c, False
    more = seed_starts(ctx, goal, seeds, cfg.family_seed_starts, c.z.shape[1])
    r = refine(ctx, more.q, goal, call.deadline, prune=True, enough=call.enough)
    more = assess(r.q, more.z, r.perr, r.oerr, goal.kind, cfg)
    return Candidates.concat(c, more), r.cut_short


def more_oriented(ctx: Context, call: Call, c: Candidates) -> Tuple[Candidates, bool]:
    """``c`` and the oriented postures a call asking for few solutions left out, refined.

    The table ranks them by orientation, so the first ones are those already refined.
    """
    cfg, goal = ctx.config, call.goal
    q = oriented_postures(ctx, goal, cfg.oriented_candidates)[oriented_count(cfg, call.num):]
    r = refine(ctx, q, goal, call.deadline, prune=True, enough=call.enough)
    more = assess(r.q, unindexed(q, c.z.shape[1]), r.perr, r.oerr, goal.kind, cfg)
    return Candidates.concat(c, more), r.cut_short


def free_rounds(ctx: Context, call: Call, c: Candidates, sols: List[Solution],
                fam: Optional[np.ndarray], atlas: Optional[Atlas] = None
                ) -> Tuple[List[Solution], Optional[np.ndarray], bool]:
    """Stage 4's restarts when every exact solution found collides with the arm itself.

    Perturbed copies and random configurations are refined for a free one, in a few rounds
    of fresh draws (goals close to the base; obstacles are Algorithm 2's). For position goals
    only, whose self-motion leaves room for a free solution (at pose goals they found none and
    cost time; none at all where the seed table's starts gave the branches: docs/design.md,
    "Measured choices").

    Returns:
        the solutions, the family roots of the candidates they were ranked from (as
        :func:`family_roots`), and whether the deadline cut a round's refinement short.
    """
    goal, deadline = call.goal, call.deadline
    rounds = 0 if not call.refined or call.seeds is not None else \
        FREE_ROUNDS if goal.kind == POSITION else 1
    timed_out = False
    for stream in range(rounds):
        if not c.exact.any() or deadline.expired() or \
                not all(s.self_collision for s in sols if s.converged):
            break
        more, cut = restart(ctx, c, goal, deadline, keep=FREE_RESTARTS, stream=stream)
        timed_out = timed_out or cut
        c = distinct_postures(ctx, more, goal, call.q_seed, atlas)
        fam = family_roots(ctx, call, c, atlas)
        sols = rank(ctx, c, call.q_seed, call.obstacles, call.objective, limit=call.num,
                    deadline=deadline, families=fam, every_family=every_family(call, atlas))
    return sols, fam, timed_out


def finish(ctx: Context, call: Call, sols: List[Solution], timed_out: bool,
           fam: Optional[np.ndarray] = None) -> IKResult:
    """Stage 5 and the answer: indices filled in, Algorithm 2 around obstacles, the result.

    ``fam``: the family roots of the candidates ranked (:func:`family_roots`): the families
    are numbered in the answer's order and counted; with ``one_per_family`` only the best
    solution of each is kept.
    """
    goal, obstacles, deadline = call.goal, call.obstacles, call.deadline
    if not call.first_found or obstacles:
        fill_indices(ctx, goal, sols)
    if obstacles and call.refined and \
            not any(s.converged and not s.in_collision for s in sols) and \
            not deadline.expired():
        extra = adjust_index(ctx, goal, sols, obstacles, deadline)
        if extra is not None:
            sols = merge(ctx, sols, extra, goal.kind, call.q_seed, obstacles, call.objective,
                         deadline)
            if not call.first_found and call.num > 1:  # ranked again, families first
                c = from_solutions(sols)
                fam = families.roots(ctx, c, goal, deadline)
                sols = rank(ctx, c, call.q_seed, obstacles, call.objective, deadline=deadline,
                            families=fam, every_family=call.isolated)
            sols = sols[:call.num]
    if fam is None and call.num == 1:  # one solution: its own family, the one known
        fam = [0] if sols and sols[0].converged else []
        for s, f in zip(sols, fam):
            s.family = f
    num_families = families.number(sols, () if fam is None else fam)
    if call.one_per_family:
        sols = families.one_per_family(sols)
    # collision checks the deadline cut short leave unknown clearances
    timed_out = timed_out or any(math.isnan(s.min_obstacle_distance) for s in sols)
    success = any(s.converged for s in sols)
    msg = '' if success else (
        'no solution within tolerance (best-effort solutions returned)' if sols else
        'no solution')
    return IKResult(success, sols, goal.kind, timed_out, message=msg,
                    num_families=num_families)
