"""The solver's settings and tuning, each value once.

:class:`SolverConfig` holds what a user (or the node's parameters) may change, validated when
made; :data:`PATH_DEFAULTS` what a path request leaves out. The module-level constants below are
the solver's fixed tuning: each with its unit and why it has its value.
"""

from dataclasses import dataclass
import math
from typing import Tuple

from sik_ros.errors import InvalidArgument
from sik_ros.kernels.angles import TURN


@dataclass(frozen=True)
class PathDefaults:
    """What a path request leaves out gets these (library, CLI and ``~/solve_path`` alike).

    Attributes:
        num_paths: ranked paths returned at most.
        max_joint_step: largest joint change between consecutive waypoints [rad].
        path_tolerance: how far the tool may leave the segment between two waypoints [m].
    """

    num_paths: int = 4
    max_joint_step: float = 0.3
    path_tolerance: float = 0.005


#: The one set of path defaults.
PATH_DEFAULTS = PathDefaults()


# -- one solve ------------------------------------------------------------------------------------

#: Metres of position error that one radian of orientation error counts as in a candidate's
#: score [m/rad] (ranking, pruning and the refinement kernel alike): 1 mrad weighs as 0.1 mm,
#: the ratio of the default tolerances.
ORIENTATION_WEIGHT = 0.1
#: A refined row converges once its errors are under this share of the tolerances (a margin
#: that keeps an answer exact after rounding and the last step's change).
CONVERGE_FACTOR = 0.5
#: A row whose errors stay above this many times the tolerances may be given up (with
#: ``give_up_after`` steps taken; :func:`sik_ros.kernels.dls.refine_rows`).
GIVE_UP_FACTOR = 10.0
#: Ranking cost of an inexact solution per metre of score [1/m]: below any exact solution's
#: objective of its tier only by the tier order, so the scale only orders inexact ones.
INEXACT_COST = 100.0
#: Oriented postures (pose goals) decoded at least, however few solutions a call asks for
#: (fewer missed the goal's branch too often).
ORIENTED_MIN = 8
#: Decoded postures closer than this share of ``distinct_threshold`` are refined once: they
#: would refine to the same solution.
START_MERGE = 0.5
#: Refinement iterations of a goal out of reach (a short best-effort answer, no retries).
FAR_ITERATIONS = 5
#: Best candidates perturbed (and as many random configurations drawn) when nothing converged.
RESTARTS = 8
#: Standard deviation of a restart's perturbation, as a share of each joint's range.
RESTART_SPREAD = 0.15
#: Perturbed copies (and as many random configurations) refined when every exact solution
#: found collides with the arm itself, in at most ``FREE_ROUNDS`` rounds of fresh draws for
#: position goals (one for pose goals, none for those the seed table gave starts); goals near
#: the base axis may need more than one round (docs/design.md).
FREE_RESTARTS = 16
FREE_ROUNDS = 3
#: The family search (:mod:`sik_ros.solver.families.search`): the tracer's step along a self-motion
#: curve [rad], most steps each way, how near a traced point a solution is on its piece
#: [rad] (a step: by a limit, a piece's last point within it may lie that far from a
#: solution), most points recorded, most new points a call and per piece.
SEARCH_STEP = 0.25
SEARCH_STEPS = 400
SEARCH_LINK = 0.25
SEARCH_RECORDED = 4096
SEARCH_POINTS = 64
SEARCH_PER_PIECE = 4
#: Most iterations refining a start across a singular angle of the arm with its last joint
#: held (:func:`sik_ros.solver.families.search.mirrored`).
MIRROR_ITERATIONS = 20
#: Seed-table starts refined for each branch code no exact solution of an isolated pose goal
#: has (:func:`sik_ros.solver.families.branches.other_branches`).
BRANCH_CODE_STARTS = 2
#: A solution whose branch sign joint is within this of its singular angle (``|sin(q_j -
#: c_j)|``, about radians near it) gets a start on the branch across that joint, for a code
#: still missing (:func:`sik_ros.solver.families.branches.mirrored`).
NEIGHBOUR_REACH = 0.3
#: The exact rows of an isolated pose goal are taken onto their solutions
#: (:func:`sik_ros.solver.families.branches.polished`): to this share of the tolerances, in at
#: most this many steps, with this damping (low enough to step along a nearly singular direction).
POLISH_FACTOR = 1e-3
POLISH_ITERATIONS = 6
POLISH_DAMPING = 1e-5
#: A polished row moved less than this [rad] (a tenth of ``SAME_BRANCH``) stays on its branch
#: unchecked: one solution with where it was by the solver's own rule.
POLISH_MOVED = 0.01
#: Most 2 pi equivalents added per solution (periodic joints): one joint turned, then two.
EQUIVALENTS_PER_SOLUTION = 16
#: Algorithm 2's move of one index element, as a share of its range in the table.
ADJUST_STEP = 0.25
#: Solutions Algorithm 2 starts from at most (the best exact ones, else the best): its budget
#: of decodes is spent on the most promising.
ADJUST_STARTS = 3
#: Metres of error that one radian of orientation counts as when raw indices are adjusted
#: [m/rad] (the ranking's 0.1 m/rad left 5.7 deg on the Panda, 0.3 3.6 deg: docs/training.md).
RAW_ORIENTATION_WEIGHT = 0.3
#: Index step of the finite differences that estimate how the decoded tip pose moves with it.
RAW_DIFFERENCE = 0.05
#: First damping of the Gauss-Newton steps on the index.
RAW_DAMPING = 0.01
#: Rounds of starts at most: a further round, of the next best candidates, only when the
#: adjusted ones came together on fewer distinct postures than the solutions asked for.
RAW_ROUNDS = 3
#: Up to this many rows a network runs as one compiled call; from more, NumPy's BLAS, whose
#: blocking pays (docs/design.md, "Measured choices").
KERNEL_ROWS = 3

#: Exact solutions of a pose goal of an arm with six joints or fewer closer than this [rad]
#: (L2, periodic joints at their nearest turn) are one solution found twice, one branch;
#: farther apart, two branches, never merged by ``distinct_threshold`` (which merges only
#: within a family). Refinements of one branch meet within a few thousandths of a radian.
SAME_BRANCH = 0.1
#: Step of a family's trace along the self-motion of a 7-joint arm at a pose [rad] (joint
#: distance; :mod:`sik_ros.solver.families.membership`): small enough that a trace keeps to
#: its curve where two pieces pass near each other (docs/design.md).
FAMILY_TRACE_STEP = 0.1
#: Most steps of a trace each way (a curve longer than this many steps may show as two
#: families).
FAMILY_TRACE_STEPS = 300
#: A solution within this many trace steps of a traced point is on the traced family.
FAMILY_LINK = 1.0
#: Step of the corrected straight segments that link solutions of a goal with more dimensions
#: of self-motion (position goals, pose goals of 8+ joints) [rad].
FAMILY_SEGMENT_STEP = 0.25
#: Solutions farther apart than this are not linked directly (only through others) [rad]: on
#: the Panda 2.5 gave the traced labels (1.0 split 3.5 % of the pairs of one family).
FAMILY_REACH = 2.5

# -- paths ----------------------------------------------------------------------------------------

#: Interpolation points checked on every edge (fractions of the edge).
EDGE_CHECKS = (0.25, 0.5, 0.75)
#: Most refinement steps of a track onto its next waypoint (a few suffice from a step away).
TRACK_ITERATIONS = 10
#: Table postures nearest the seed among which a position path's starts are chosen.
NEAR_POOL = 48
#: Most refinement steps of a position path's starts onto the first waypoint (docs/design.md).
START_ITERATIONS = 25
#: The beam of pose paths (see :class:`~sik_ros.solver.path.PathSettings`; the choice in
#: docs/design.md).
POSE_BEAM = {'starts': 10, 'tracks': 10, 'ladder': 16}
#: The beam of position paths. A position waypoint leaves a redundant arm ``n - 3`` dimensions
#: of self-motion, so a track is seldom lost and a narrow beam keeps the paths as short
#: (docs/design.md).
POSITION_BEAM = {'starts': 4, 'tracks': 4, 'ladder': 64}
#: How far the tool's orientation may leave the turn between two pose waypoints [rad].
ORIENTATION_PATH_TOLERANCE = 0.05
#: Cost of a path's start per radian of distance from the seed, against its travel [1].
SEED_WEIGHT = 1.0
#: Candidates of a waypoint closer than this are one [rad] (tracks that merged).
SAME_CANDIDATE = 1e-3
#: Paths whose starts are closer than this on every joint start alike [rad]: only the best is
#: returned, the others are no distinct alternative.
SAME_START = 1e-6


@dataclass(frozen=True)
class SolverConfig:
    """Tuning of the solver.

    Attributes:
        position_tolerance: a solution is exact when its position error is below this [m].
        orientation_tolerance: ... and its orientation error below this [rad] (pose goals).
        max_solutions_cap: largest ``num_solutions`` accepted.
        k_cells: table cells pooled around the goal.
        num_candidates: posture indices decoded per call for position goals (at least
            ``candidates_per_solution`` times the solutions asked for).
        candidates_per_solution: see above.
        pose_candidates: the same for pose goals (the pose model's indices), counting the
            oriented postures below. 0 (the default) decodes the pose model's indices only where
            the oriented postures fall short of ``candidates_per_solution`` per solution asked
            for (large requests, bundles without an orientation-aware position table); see
            docs/design.md for why.
        oriented_candidates: for pose goals, also this many postures from the position model:
            the indices of its table (when it keeps orientations) whose rows' tip orientations
            were nearest the goal's, decoded at the goal position, the last joint then turned
            in closed form towards the goal orientation. 0 disables it. A call asking for
            fewer solutions takes fewer: twice the solutions asked for, at least 8 (all of
            them when none of those refines to an exact solution).
        oriented_cells: table cells pooled around the goal for those.
        raw_candidates: posture indices decoded when ``refine`` is off: the most accurate
            distinct decoded postures are returned, so a larger pool gives better raw answers.
        raw_adjust: raw answers to pose goals: damped Gauss-Newton steps of the paper's
            Algorithm 2 on the best candidates' posture indices, with the tip pose error as
            the evaluation function (:func:`sik_ros.solver.adjust.adjust_raw`; the answers
            stay decoded postures); 0 disables it.
        refine_iterations: most damped least squares iterations.
        damping: damping of the least squares steps.
        max_step: largest joint change per iteration [rad] (also per step of a path's
            tracks onto the next waypoint).
        distinct_threshold: solutions closer than this (L2 over the joints that move the tool
            centre point for position goals) are duplicates [rad]; below 2 pi. Exact pose
            solutions of an arm of six joints or fewer are duplicates only within
            :data:`SAME_BRANCH` (two branches are never merged).
        adjust_budget: decodes Algorithm 2 may spend adjusting an index.
        give_up_after: refinement iterations after which a candidate still ten tolerances away
            is dropped.
        reach_margin: a goal farther than this from every table cell is treated as out of
            reach: a short best-effort refinement, no retries [m].
        prune_at: refinement iterations at which candidates heading for the same solution
            are merged (the one with the lower error goes on).
        prune_radius: joint distance under which two candidates are merged there [rad].
        stall_window, stall_ratio: a candidate not yet exact whose error is above
            ``stall_ratio`` times its error ``stall_window`` iterations before is dropped
            (0 disables it), from iteration ``stall_after`` on; ``give_up_after`` still bounds
            those still ten tolerances away.
        early_stop_margin: with the default ranking (no seed, obstacles or objective),
            refinement stops once ``num_solutions`` plus this many (at most
            ``num_solutions - 1``) distinct exact solutions are found, instead of refining
            every candidate to its end; -1 disables it.
        cached_postures: refine from the table's decoded postures (each index decoded at its
            cell's centre when the table was built, ``sik-index --postures``) instead of
            decoding the candidates at the goal at every call; raw answers
            (``refine=False``) are always decoded at the goal.
        walk_rounds: pose goals of redundant arms the family search does not follow (8 or
            more joints, or ``family_search`` off): while fewer than ``num_solutions`` (plus
            the margin above) distinct exact solutions are found, up to this many rounds of
            steps along the self-motion manifolds of the found ones (0 disables it): each
            solution, moved
            ``walk_step`` [rad] along the null space of its Jacobian (both ways from the
            refined solutions, then onwards), is refined for at most ``walk_iterations``
            iterations; the new exact solutions at least ``distinct_threshold`` from every
            found one are kept and walk on.
        max_obstacles: most obstacles a request may give (their checks bound its work).
        max_waypoints: most waypoints a path request may give (its work and memory grow
            with them).
        branch_restarts: pose goals of arms with six joints or fewer (isolated solutions, no
            self-motion): starts drawn uniformly in joint space and refined, for the branches
            the candidates missed (0 disables it). Used where the seed table is not: bundles
            without one, or ``seed_starts`` 0.
        seed_starts: pose goals of arms with six joints or fewer whose bundle has a seed
            table (:mod:`sik_ros.tables.seed_table`): up to this many starts from it, the dataset
            configurations nearest the goal pose chosen far apart in joint space (no two
            within ``seed_table.START_SPACING``, at least ``START_LEAST``), in place of
            the oriented and table postures and of the ``branch_restarts`` random ones (0: those
            instead). 7-joint arms: ``family_seed_starts``.
        seed_neighbours: the configurations nearest the goal pose (by tip position [m] and
            0.3 m per unit of quaternion distance) that those are chosen among.
        one_per_family: return at most one solution per posture family (the best of each,
            :mod:`sik_ros.solver.families.membership`) instead of filling ``num_solutions``
            with more solutions of the families already given.
        family_search: pose goals of a 7-joint arm asking for more than one solution: follow
            the self-motion curves of the solutions found (and of their mirrors across the
            arm's singular angles with the last joint held) past the joint limits, every
            piece within the limits a family, and give points far apart on each
            (:mod:`sik_ros.solver.families.search`), in place of the walk. On by default; off,
            a call walks instead and covers fewer of a pose's families (docs/benchmarks.md).
        family_seed_starts: those calls' starts from the bundle's seed table (7-joint arms
            have a small one, :func:`~sik_ros.tables.seed_table.default_rows`): up to this
            many, chosen as ``seed_starts`` are, refined with the model's postures; curves
            no model posture leads to are traced from them (0: none).
    """

    position_tolerance: float = 1e-4
    orientation_tolerance: float = 1e-3
    max_solutions_cap: int = 64
    k_cells: int = 8
    num_candidates: int = 20
    candidates_per_solution: float = 1.25
    pose_candidates: int = 0
    oriented_candidates: int = 32
    oriented_cells: int = 27
    raw_candidates: int = 192
    raw_adjust: int = 4
    refine_iterations: int = 40
    damping: float = 1e-3
    max_step: float = 0.6
    distinct_threshold: float = 0.5
    adjust_budget: int = 24
    reach_margin: float = 0.15
    give_up_after: int = 15
    prune_at: Tuple[int, ...] = (3, 6, 10)
    prune_radius: float = 0.25
    stall_window: int = 3
    stall_ratio: float = 0.7
    stall_after: int = 4
    early_stop_margin: int = 2
    cached_postures: bool = True
    walk_rounds: int = 6
    walk_step: float = 0.6
    walk_iterations: int = 4
    max_obstacles: int = 256
    max_waypoints: int = 2000
    branch_restarts: int = 48
    seed_starts: int = 24
    seed_neighbours: int = 100
    one_per_family: bool = False
    family_search: bool = True
    family_seed_starts: int = 16

    def __post_init__(self):
        """Reject values the solver cannot work with.

        Raises:
            InvalidArgument: naming the field and the value.
        """
        for name in ('position_tolerance', 'orientation_tolerance', 'candidates_per_solution',
                     'damping', 'max_step', 'distinct_threshold', 'reach_margin',
                     'prune_radius', 'stall_ratio', 'walk_step'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value) or value <= 0:
                raise InvalidArgument(f'SolverConfig.{name} must be a finite number > 0; got '
                                      f'{value!r}')
        for name, low in (('max_solutions_cap', 1), ('k_cells', 1), ('num_candidates', 0),
                          ('pose_candidates', 0), ('oriented_candidates', 0),
                          ('oriented_cells', 1), ('raw_candidates', 1), ('raw_adjust', 0),
                          ('refine_iterations', 1), ('adjust_budget', 0), ('give_up_after', 1),
                          ('stall_window', 0), ('stall_after', 0), ('early_stop_margin', -1),
                          ('walk_rounds', 0), ('walk_iterations', 1), ('max_obstacles', 0),
                          ('max_waypoints', 1), ('branch_restarts', 0), ('seed_starts', 0),
                          ('seed_neighbours', 1), ('family_seed_starts', 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise InvalidArgument(f'SolverConfig.{name} must be an integer >= {low}; got '
                                      f'{value!r}')
        for name in ('one_per_family', 'family_search'):
            if not isinstance(getattr(self, name), bool):
                raise InvalidArgument(f'SolverConfig.{name} must be a bool; got '
                                      f'{getattr(self, name)!r}')
        if self.distinct_threshold >= TURN:
            # 2 pi equivalents of a posture are told apart by a whole turn of some joint
            raise InvalidArgument(f'SolverConfig.distinct_threshold must be below 2 pi; got '
                                  f'{self.distinct_threshold!r}')
        if not isinstance(self.prune_at, (tuple, list)) or not all(
                isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in self.prune_at):
            raise InvalidArgument(f'SolverConfig.prune_at must hold integers >= 0; got '
                                  f'{self.prune_at!r}')
