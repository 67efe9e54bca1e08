"""Algorithm 2 of the paper: adjust posture indices while the clearance from obstacles improves."""

from typing import List, Optional, Sequence

import numpy as np

from sik_ros.collision import Obstacle
from sik_ros.deadline import Deadline, NO_DEADLINE
from sik_ros.solver.codec import decode
from sik_ros.solver.config import ADJUST_STARTS, ADJUST_STEP
from sik_ros.solver.context import Context, Goal
from sik_ros.solver.ranking import converged
from sik_ros.solver.refine import refine
from sik_ros.solver.results import Solution


def adjust_index(ctx: Context, goal: Goal, sols: Sequence[Solution],
                 obstacles: Sequence[Obstacle], deadline: Deadline = NO_DEADLINE,
                 step: float = ADJUST_STEP) -> Optional[List[Solution]]:
    """Move posture indices element by element while the clearance improves.

    Starts from the best colliding solutions; each trial decodes and refines the neighbours of
    an index (one element moved by ``step`` times its range in the table, either way); it
    stops at a collision-free exact solution or when ``config.adjust_budget`` decodes are
    spent.

    Returns:
        the improving solutions found, last best, or None.
    """
    cfg = ctx.config
    starts = [s for s in sols if s.converged][:ADJUST_STARTS] or list(sols[:ADJUST_STARTS])
    budget = cfg.adjust_budget
    found: List[Solution] = []
    lo, hi = ctx.models[goal.kind].table.index_bounds
    for s in starts:
        z = s.posture_index.astype(np.float64)
        best = s.min_obstacle_distance
        while budget > 0 and not deadline.expired():
            trials = []
            for d in range(len(z)):
                for sign in (1.0, -1.0):
                    t = z.copy()
                    t[d] = np.clip(t[d] + sign * step * (hi[d] - lo[d]), lo[d], hi[d])
                    trials.append(t)
            trials = np.array(trials)
            budget -= len(trials)
            r = refine(ctx, decode(ctx, goal, trials), goal, deadline)
            exact = converged(r.perr, r.oerr, goal.kind, cfg)
            clear = ctx.checker.clearance(r.q, obstacles, deadline)
            clear = np.where(ctx.checker.self_collision(r.q) | ~exact | np.isnan(clear), -np.inf,
                             clear)
            i = int(np.argmax(clear))
            if clear[i] <= best:
                break
            best, z = clear[i], trials[i]
            found.append(Solution(r.q[i], float(r.perr[i]), float(r.oerr[i]),
                                  trials[i].astype(np.float32), 0.0, float(clear[i]),
                                  False, True))
            if best > 0:
                break
        if found and found[-1].min_obstacle_distance > 0:
            break
    return found or None
