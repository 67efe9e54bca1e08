"""Every branch of an isolated pose goal: starts for the branches missed, rows polished.

A pose of an arm with six joints or fewer has isolated solutions, its branches
(:mod:`sik_ros.kinematics.branches`: each with a branch code). After the seed table's starts
are refined, :func:`other_branches` gives starts to the codes no exact row has: the table's rows
of each code, the arm's exact flips of the solutions found, then (a second round, for the codes
still missing) the flips of the new solutions and their neighbours across a sign joint
(:func:`mirrored`). :func:`polished` then takes every exact row onto the solution it stands
for: near a singularity a row within the tolerances can lie a branch's reach from it.
"""

import functools
from typing import Optional, Set

import numpy as np

from sik_ros.deadline import Deadline
from sik_ros.kernels import as_arg
from sik_ros.kernels.angles import TURN, turned_rows
from sik_ros.kernels.dls import POLISH, polish_rows
from sik_ros.kinematics.branches import BranchSigns, flip, robot_flips
from sik_ros.kinematics.robot import Robot
from sik_ros.solver.config import (BRANCH_CODE_STARTS, NEIGHBOUR_REACH, ORIENTATION_WEIGHT,
                                   POLISH_DAMPING, POLISH_FACTOR, POLISH_ITERATIONS,
                                   POLISH_MOVED)
from sik_ros.solver.context import Context, Goal
from sik_ros.solver.refine import refine, Refined
from sik_ros.solver.scores import converged
from sik_ros.tables.seed_table import SeedTable


def other_branches(ctx: Context, goal: Goal, seeds: SeedTable, r: Refined,
                   deadline: Deadline) -> Refined:
    """``r`` (refined starts of an isolated pose goal) and starts on the branches it missed.

    Each exact row's branch code (:mod:`sik_ros.kinematics.branches`) is read; for every code
    none has, the seed table's rows of that code nearest the goal pose
    (:meth:`~sik_ros.tables.seed_table.SeedTable.branch_starts`, :data:`BRANCH_CODE_STARTS`
    of them) are refined and appended, with the exact flips of the rows found. The nearest rows
    of the whole table can all lie on a few branches; a code's own rows lie on its branch
    wherever the goal is. Codes still missing then get starts from the solutions found: the
    flips of those of the code starts, and their neighbours across a sign joint
    (:func:`mirrored`), refined and appended too.
    """
    signs = seeds.signs
    if signs is None:
        return r
    found = exact_codes(ctx, goal, signs, r)
    starts = [seeds.branch_starts(goal.position, goal.quaternion, code, BRANCH_CODE_STARTS,
                                  ctx.config.seed_neighbours)
              for code in range(signs.count) if code not in found]
    if not starts or deadline.expired():
        return r
    coded = sum(len(s) for s in starts)  # the code starts, then the flips of the rows found
    starts.append(flipped(ctx, r.q[converged(r.perr, r.oerr, goal.kind, ctx.config)]))
    more = refine(ctx, np.concatenate(starts), goal, deadline)
    r = joined(r, more)
    if deadline.expired() or not (len(robot_flips(ctx.robot)) or
                                  len(mirror_bits(ctx.robot, signs))):
        return r
    # a second round, for the codes still missing: the flips of the code starts' solutions,
    # and the branches next to a solution across a sign joint
    new = converged(more.perr[:coded], more.oerr[:coded], goal.kind, ctx.config)
    flips = flipped(ctx, more.q[:coded][new])
    near = mirrored(ctx, signs, r.q[converged(r.perr, r.oerr, goal.kind, ctx.config)])
    if not len(flips) and not len(near):
        return r
    missing = list(set(range(signs.count)) - found - exact_codes(ctx, goal, signs, more))
    if not missing:
        return r
    q = np.concatenate([flips, near[np.isin(signs.codes(ctx.robot, near), missing)]])
    return joined(r, refine(ctx, q, goal, deadline)) if len(q) else r


def exact_codes(ctx: Context, goal: Goal, signs: BranchSigns, r: Refined) -> Set[int]:
    """The branch codes of ``r``'s exact rows."""
    exact = converged(r.perr, r.oerr, goal.kind, ctx.config)
    return set(signs.codes(ctx.robot, r.q[exact]).tolist()) if exact.any() else set()


def joined(a: Refined, b: Refined) -> Refined:
    """The rows of ``a`` then those of ``b``."""
    return Refined(np.concatenate([a.q, b.q]), np.concatenate([a.perr, b.perr]),
                   np.concatenate([a.oerr, b.oerr]), a.cut_short or b.cut_short)


def flipped(ctx: Context, q: np.ndarray) -> np.ndarray:
    """The arm's exact flips of solutions ``q`` (M, n) that fit its limits (K, n).

    An exact flip (a spherical wrist turned over: :func:`~sik_ros.kinematics.branches.flip`)
    reaches the same pose on another branch; every angle is turned by whole turns into its
    limits (the same placement), and rows that do not fit are dropped.
    """
    robot = ctx.robot
    out = [np.empty((0, robot.dof))]
    for a in robot_flips(robot) if len(q) else ():
        f = flip(q, a)
        out.append(f[turned_rows(f, robot.lower, robot.upper, f)])
    return np.concatenate(out)


def mirrored(ctx: Context, signs: BranchSigns, q: np.ndarray) -> np.ndarray:
    """Starts (K, n) on the branches next to solutions ``q`` (M, n) across a sign joint.

    A solution whose sign joint stands within :data:`NEIGHBOUR_REACH` (of ``sin``) of its
    singular angle (a UR5's elbow nearly stretched) has the branch on the joint's other side
    close by, where a table row of that branch's code, farther off, refines onto the solution
    found instead. Its start: the solution with that joint mirrored about its singular angle
    (its code then differs in that joint's bit and the determinant's); every angle turned into
    the limits, rows that do not fit dropped.
    """
    robot = ctx.robot
    bits = mirror_bits(robot, signs)
    joints, centres = signs.joint_array[bits], signs.centre_array[bits]
    rows, k = np.nonzero(np.abs(np.sin(q[:, joints] - centres)) < NEIGHBOUR_REACH)
    if not len(rows):
        return np.empty((0, robot.dof))
    m = q[rows]
    m[np.arange(len(rows)), joints[k]] = 2 * centres[k] - m[np.arange(len(rows)), joints[k]]
    return m[turned_rows(m, robot.lower, robot.upper, m)]


@functools.lru_cache(maxsize=16)
def mirror_bits(robot: Robot, signs: BranchSigns) -> np.ndarray:
    """The sign joints (their bits, int64) whose mirror about the singular angle can fit.

    :func:`fits_mirrored`: the Z1's wrist (limits +-1.34 rad about its singular angle pi/2
    away) has none.
    """
    fits = [fits_mirrored(robot, j, c) for j, c in zip(signs.joints, signs.centres)]
    return np.flatnonzero(np.array(fits, dtype=bool)).astype(np.int64)


def fits_mirrored(robot: Robot, j: int, c: float) -> bool:
    """Whether joint ``j``'s angle mirrored about ``c`` [rad] can fit its limits.

    Mirrored and turned by whole turns, for some angle within them (one of 360 across them).
    """
    lower, upper = robot.lower[j], robot.upper[j]
    mirror = 2 * c - np.linspace(lower, upper, 360)
    return bool(np.any(lower + np.mod(mirror - lower, TURN) <= upper))


@functools.lru_cache(maxsize=64)
def polish_settings(cfg) -> np.ndarray:
    """:func:`~sik_ros.kernels.dls.polish_rows`'s settings (:data:`~sik_ros.kernels.dls.POLISH`).

    Shared, made once per configuration: not to be written.
    """
    values = {'position_tolerance': cfg.position_tolerance * POLISH_FACTOR,
              'orientation_tolerance': cfg.orientation_tolerance * POLISH_FACTOR,
              'damping2': POLISH_DAMPING ** 2, 'max_step': cfg.max_step,
              'orientation_weight': ORIENTATION_WEIGHT, 'iterations': POLISH_ITERATIONS}
    return np.array([values[k] for k in POLISH], dtype=float)


def polished(ctx: Context, goal: Goal, signs: Optional[BranchSigns], r: Refined) -> Refined:
    """``r`` with its exact rows taken closer onto the goal, each kept on its branch.

    Near a singularity the goal's error grows slowly along some direction of joint space, and
    a configuration within the tolerances may lie a tenth of a radian or more from the
    solution it stands for (its error over the Jacobian's smallest singular value): two rows of
    one solution then look like two branches, and a branch's row can look like another's
    (0.1 rad apart, :data:`~sik_ros.solver.config.SAME_BRANCH`). Nearly undamped steps
    (:data:`POLISH_DAMPING`, at most :data:`POLISH_ITERATIONS`) to :data:`POLISH_FACTOR` of
    the tolerances take each onto its solution, within the limits
    (:func:`~sik_ros.kernels.dls.polish_rows`); a row whose error they would not lower, or
    whose branch code they would change (checked where they move it :data:`POLISH_MOVED` or
    more), is kept as it was.
    """
    cfg, robot = ctx.config, ctx.robot
    rows = np.flatnonzero(converged(r.perr, r.oerr, goal.kind, cfg))
    if not len(rows):
        return r
    q, perr, oerr = r.q.copy(), r.perr.copy(), r.oerr.copy()
    moved = np.empty(len(rows))
    polish_rows(robot.frames, robot.lower, robot.upper, robot.periodic, q, rows,
                as_arg(goal.position), as_arg(goal.rotation), polish_settings(cfg), perr, oerr,
                moved)
    far = rows[moved >= POLISH_MOVED]  # nearer: one solution with where it was by any rule
    if signs is not None and len(far):
        back = far[signs.codes(robot, q[far]) != signs.codes(robot, r.q[far])]
        q[back], perr[back], oerr[back] = r.q[back], r.perr[back], r.oerr[back]
    return Refined(q, perr, oerr, r.cut_short)
