"""SelectiveIK: several distinct, exact, ranked joint solutions per target.

Pipeline per call: posture indices from the table near the goal (plus the seed's own index),
a far-apart subset, their postures (the table's decoded postures at the cells' centres when it
keeps them, else one batched decode at the goal; raw answers are always decoded at the goal),
clipping to the joint limits, batched damped least squares refinement on the chain's Jacobians
(for pose goals, then steps along the self-motion manifolds of the solutions found), verification
by FK, removal of near-duplicate postures, collision checks and ranking. See the paper's
"Posture index selection" and Algorithm 2.
"""

from dataclasses import dataclass, field, fields, replace
import json
import math
from pathlib import Path
import threading
import time
from typing import Dict, List, Optional, Sequence, Tuple, Union
import zlib

import numpy as np
from scipy.spatial.distance import cdist
from scipy.spatial.transform import Rotation
import torch

from sik_ros.artifacts import check_robot_manifest, read_json
from sik_ros.errors import (ArtifactMismatch, CorruptArtifact, InvalidArgument, InvalidGoal,
                            InvalidSeed, JointLimitViolation)
from sik_ros.index_table import farthest_point_subset, IndexTable, model_signature
from sik_ros.kinematics import load_robot, Robot
from sik_ros.models import make_goal
from sik_ros.objectives import (CollisionChecker, JointLimitMargin, Objective, Obstacle,
                                SeedDistance)
from sik_ros.training import load_checkpoint, model_from_checkpoint

BUNDLES = Path(__file__).resolve().parent / 'models'


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
        pose_candidates: the same for pose goals (the pose model's indices).
        oriented_candidates: for pose goals, also this many postures from the position model:
            the indices of its table (when it keeps orientations) whose rows' tip orientations
            were nearest the goal's, decoded at the goal position, the last joint then turned
            in closed form towards the goal orientation. 0 disables it.
        oriented_cells: table cells pooled around the goal for those.
        raw_candidates: posture indices decoded when ``refine`` is off: the most accurate
            distinct decoded postures are returned, so a larger pool gives better raw answers.
        refine_iterations: most damped least squares iterations.
        damping: damping of the least squares steps.
        max_step: largest joint change per iteration [rad].
        distinct_threshold: solutions closer than this (L2 over the joints that move the tool
            centre point for position goals) are duplicates [rad].
        adjust_budget: decodes Algorithm 2 may spend adjusting an index.
        give_up_after: refinement iterations after which a candidate still ten tolerances away
            is dropped.
        reach_margin: a goal farther than this from every table cell is treated as out of
            reach: a short best-effort refinement, no retries [m].
        prune_at: refinement iterations at which candidates heading for the same solution
            are merged (the one with the lower error goes on).
        prune_radius: joint distance under which two candidates are merged there [rad].
        stall_window, stall_ratio: a candidate still ten tolerances away whose error is above
            ``stall_ratio`` times its error ``stall_window`` iterations before is dropped
            (0 disables it), from iteration ``stall_after`` on; ``give_up_after`` still bounds
            the rest.
        early_stop_margin: with the default ranking (no seed, obstacles or objective),
            refinement stops once ``num_solutions`` plus this many distinct exact solutions are
            found, instead of refining every candidate to its end; -1 disables it.
        cached_postures: refine from the table's decoded postures (each index decoded at its
            cell's centre when the table was built, ``sik-index --postures``) instead of
            decoding the candidates at the goal at every call; raw answers
            (``refine=False``) are always decoded at the goal.
        walk_rounds: pose goals: while fewer than ``num_solutions`` (plus the margin above)
            distinct exact solutions are found, up to this many rounds of steps along the
            self-motion manifolds of the found ones (0 disables it): each solution, moved
            ``walk_step`` [rad] along the null space of its Jacobian (both ways from the
            refined solutions, then onwards), is refined for at most ``walk_iterations``
            iterations; the new exact solutions at least ``distinct_threshold`` from every
            found one are kept and walk on.
    """

    position_tolerance: float = 1e-4
    orientation_tolerance: float = 1e-3
    max_solutions_cap: int = 64
    k_cells: int = 8
    num_candidates: int = 20
    candidates_per_solution: float = 1.25
    pose_candidates: int = 4
    oriented_candidates: int = 32
    oriented_cells: int = 27
    raw_candidates: int = 192
    refine_iterations: int = 40
    damping: float = 1e-3
    max_step: float = 0.4
    distinct_threshold: float = 0.5
    adjust_budget: int = 24
    reach_margin: float = 0.15
    give_up_after: int = 15
    prune_at: Tuple[int, ...] = (3, 6, 10)
    prune_radius: float = 0.25
    stall_window: int = 3
    stall_ratio: float = 0.7
    stall_after: int = 8
    early_stop_margin: int = 2
    cached_postures: bool = True
    walk_rounds: int = 6
    walk_step: float = 0.6
    walk_iterations: int = 4

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
                          ('oriented_cells', 1), ('raw_candidates', 1),
                          ('refine_iterations', 1), ('adjust_budget', 0), ('give_up_after', 1),
                          ('stall_window', 0), ('stall_after', 0), ('early_stop_margin', -1),
                          ('walk_rounds', 0), ('walk_iterations', 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise InvalidArgument(f'SolverConfig.{name} must be an integer >= {low}; got '
                                      f'{value!r}')
        if not all(isinstance(v, int) and not isinstance(v, bool) and v >= 0
                   for v in self.prune_at):
            raise InvalidArgument(f'SolverConfig.prune_at must hold integers >= 0; got '
                                  f'{self.prune_at!r}')


def rotation_log(rot: np.ndarray) -> np.ndarray:
    """Rotation vectors (N, 3) [rad] of rotation matrices (N, 3, 3) (the SO(3) logarithm)."""
    v = 0.5 * np.stack([rot[:, 2, 1] - rot[:, 1, 2], rot[:, 0, 2] - rot[:, 2, 0],
                        rot[:, 1, 0] - rot[:, 0, 1]], axis=1)
    sin = np.sqrt((v * v).sum(1))
    cos = np.clip((rot[:, 0, 0] + rot[:, 1, 1] + rot[:, 2, 2] - 1) / 2, -1.0, 1.0)
    angle = np.arctan2(sin, cos)
    out = v * np.where(sin > 1e-9, angle / np.maximum(sin, 1e-12), 1.0)[:, None]
    near_pi = (sin < 1e-6) & (cos < 0)
    if near_pi.any():  # the skew part vanishes at pi: take the axis from R + I
        out[near_pi] = Rotation.from_matrix(rot[near_pi]).as_rotvec()
    return out


@dataclass
class Solution:
    """One joint solution.

    Attributes:
        q: joint positions (n,) [rad], within the limits.
        position_error: distance from the tip to the target [m].
        orientation_error: angle between tip and target orientation [rad] (0 for position goals).
        posture_index: the posture index that produced it.
        score: ranking score, lower is better.
        min_obstacle_distance: clearance from the obstacles [m] (+inf without obstacles).
        self_collision: whether the posture collides with itself.
        converged: whether it meets the tolerances.
    """

    q: np.ndarray
    position_error: float
    orientation_error: float
    posture_index: np.ndarray
    score: float = 0.0
    min_obstacle_distance: float = float('inf')
    self_collision: bool = False
    converged: bool = False

    @property
    def in_collision(self) -> bool:
        """Whether it touches an obstacle or itself."""
        return self.self_collision or self.min_obstacle_distance <= 0.0


@dataclass
class IKResult:
    """The answer to one target: ranked solutions, best first."""

    success: bool
    solutions: List[Solution] = field(default_factory=list)
    goal: str = 'position'
    timed_out: bool = False
    elapsed: float = 0.0
    message: str = ''


@dataclass
class _GoalModel:
    model: torch.nn.Module
    cfg: object
    norm: object
    table: IndexTable


class SelectiveIK:
    """Multi-solution IK from trained SIK models and their posture-index tables.

    Not thread-safe per instance (Pinocchio data); :meth:`clone` gives an instance sharing the
    models and tables for another thread. Calls on one instance are serialised by a lock.
    """

    def __init__(self, robot: Robot, models: Dict[str, _GoalModel],
                 config: Optional[SolverConfig] = None, bundle: Optional[Path] = None):
        self.robot = robot
        self.models = models
        self.config = config or SolverConfig()
        self.bundle = bundle
        self.checker = CollisionChecker(robot)
        self._lock = threading.Lock()
        self._cut_short = False
        self._data = robot.model.createData()

    # -- loading ---------------------------------------------------------------------------------

    @classmethod
    def load(cls, bundle: Union[str, Path] = 'panda',
             config: Optional[SolverConfig] = None) -> 'SelectiveIK':
        """Load a bundle: a name of the bundled models (``panda``) or a bundle directory.

        Raises:
            CorruptArtifact: a missing or damaged file.
            ArtifactMismatch: files made for another robot or model.
        """
        path = Path(bundle)
        if not path.is_dir():
            if (BUNDLES / str(bundle)).is_dir():
                path = BUNDLES / str(bundle)
            else:
                known = sorted(p.name for p in BUNDLES.iterdir() if p.is_dir()) \
                    if BUNDLES.is_dir() else []
                raise CorruptArtifact(f'no bundle {bundle!r}: not a directory, and the bundled '
                                      f'models are {known}')
        manifest = read_json(path / 'bundle.json', f'bundle {path}')
        if manifest.get('kind') != 'sik_bundle':
            raise CorruptArtifact(f'{path}/bundle.json is not a sik_ros bundle manifest')
        rm = manifest['robot']
        robot = load_robot(rm['robot'], rm.get('urdf'), rm['base_frame'], rm['tip_frame'])
        check_robot_manifest(f'bundle {path}', robot.manifest(), rm)
        models = {}
        for goal, files in manifest['models'].items():
            ckpt = load_checkpoint(path / files['model'])
            check_robot_manifest(f'model {files["model"]}', robot.manifest(), ckpt['robot'])
            model, cfg, norm = model_from_checkpoint(ckpt)
            if cfg.goal != goal or cfg.kind not in ('sik', 'psik'):
                raise ArtifactMismatch(f'bundle {path}: model for {goal} goals', goal,
                                       f'{cfg.kind}/{cfg.goal}')
            table = IndexTable.load(path / files['table'], robot.manifest(),
                                    model_signature(ckpt))
            models[goal] = _GoalModel(model, cfg, norm, table)
        if not models:
            raise CorruptArtifact(f'bundle {path} lists no models')
        return cls(robot, models, config, path)

    def clone(self) -> 'SelectiveIK':
        """An instance sharing models and tables, with its own Pinocchio/coal data."""
        return SelectiveIK(self.robot, self.models, self.config, self.bundle)

    def with_config(self, **changes) -> 'SelectiveIK':
        """An instance with some :class:`SolverConfig` fields changed.

        Raises:
            InvalidArgument: an unknown field or a bad value.
        """
        unknown = sorted(set(changes) - {f.name for f in fields(SolverConfig)})
        if unknown:
            raise InvalidArgument(f'unknown SolverConfig fields {unknown}')
        return SelectiveIK(self.robot, self.models, replace(self.config, **changes), self.bundle)

    # -- public helpers --------------------------------------------------------------------------

    @property
    def joint_names(self) -> List[str]:
        """Arm joint names, in the order of every ``q``."""
        return list(self.robot.joint_names)

    @property
    def goals(self) -> List[str]:
        """Goal kinds this bundle answers (``position``, ``pose``)."""
        return sorted(self.models)

    def fk(self, q: np.ndarray):
        """Tip position (3,) [m] and quaternion (4,) x y z w of a configuration (n,)."""
        q = np.asarray(q, dtype=float)
        if q.shape != (self.robot.dof,):
            raise InvalidArgument(f'q must have shape ({self.robot.dof},); got {q.shape}')
        return self.robot.fk(q)

    # -- validation ------------------------------------------------------------------------------

    def _check_inputs(self, position, orientation, num_solutions, seed):
        try:
            pos = np.asarray(position, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InvalidGoal(f'position must be 3 numbers; got {position!r}') from exc
        if pos.shape != (3,):
            raise InvalidGoal(f'position must have 3 elements; got shape {pos.shape}')
        if not np.all(np.isfinite(pos)):
            raise InvalidGoal(f'position must be finite; got {pos.tolist()}')
        rot = None
        if orientation is not None:
            try:
                quat = np.asarray(orientation, dtype=float)
            except (TypeError, ValueError) as exc:
                raise InvalidGoal(f'orientation must be a quaternion; got {orientation!r}') \
                    from exc
            if quat.shape != (4,):
                raise InvalidGoal(f'orientation must be a quaternion (x, y, z, w); got shape '
                                  f'{quat.shape}')
            if not np.all(np.isfinite(quat)):
                raise InvalidGoal(f'orientation must be finite; got {quat.tolist()}')
            norm = np.linalg.norm(quat)
            if norm < 1e-9:
                raise InvalidGoal('orientation quaternion is zero')
            rot = Rotation.from_quat(quat / norm).as_matrix()
        goal = 'position' if rot is None else 'pose'
        if goal not in self.models:
            raise InvalidGoal(f'this bundle has no model for {goal} goals (it has {self.goals})')
        if isinstance(num_solutions, bool) or not isinstance(num_solutions, (int, np.integer)):
            raise InvalidArgument(f'num_solutions must be an integer; got {num_solutions!r}')
        cap = self.config.max_solutions_cap
        if not 1 <= num_solutions <= cap:
            raise InvalidArgument(f'num_solutions must be between 1 and {cap}; got '
                                  f'{num_solutions}')
        q_seed = None
        if seed is not None:
            q_seed = self.check_seed(seed)
        return pos, rot, goal, q_seed

    def check_seed(self, seed) -> np.ndarray:
        """A seed as a (n,) array, or :class:`InvalidSeed` saying what is wrong with it."""
        try:
            q = np.asarray(seed, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InvalidSeed(f'seed must be {self.robot.dof} numbers; got {seed!r}') from exc
        if q.shape != (self.robot.dof,):
            raise InvalidSeed(f'seed must have {self.robot.dof} joint values '
                              f'({", ".join(self.joint_names)}); got shape {q.shape}')
        if not np.all(np.isfinite(q)):
            raise InvalidSeed(f'seed must be finite; got {q.tolist()}')
        eps = 1e-6
        for name, v, lo, hi in zip(self.joint_names, q, self.robot.lower, self.robot.upper):
            if v < lo - eps or v > hi + eps:
                raise JointLimitViolation(name, float(v), float(lo), float(hi))
        return np.clip(q, self.robot.lower, self.robot.upper)

    # -- solving ---------------------------------------------------------------------------------

    def solve(self, position, orientation=None, num_solutions: int = 16, seed=None,
              obstacles: Sequence[Obstacle] = (), refine: bool = True,
              objective: Optional[Objective] = None, timeout: Optional[float] = None
              ) -> IKResult:
        """Ranked joint solutions for one target.

        Args:
            position: target tip position in the base frame (3,) [m].
            orientation: None for a position goal; else a quaternion (x, y, z, w).
            num_solutions: most solutions returned (1 to ``max_solutions_cap``).
            seed: current joint configuration (n,) [rad]: its posture index is tried first and
                ranking prefers solutions near it.
            obstacles: :class:`Obstacle` list; colliding solutions never rank above free ones.
            refine: refine the decoded solutions numerically (False: raw decoder output).
            objective: custom ranking cost (lower is better); default: distance to the seed
                if given, else closeness to the joint limits.
            timeout: give up refining after this many seconds [s].

        Raises:
            InvalidGoal, InvalidSeed, InvalidArgument: bad input (see INTERFACES.md).
        """
        t0 = time.perf_counter()
        pos, rot, goal, q_seed = self._check_inputs(position, orientation, num_solutions, seed)
        obstacles = [o if isinstance(o, Obstacle) else Obstacle(**o) for o in obstacles]
        with self._lock:
            result = self._solve(pos, rot, goal, num_solutions, q_seed, obstacles, refine,
                                 objective, timeout, t0)
        result.elapsed = time.perf_counter() - t0
        return result

    def solve_batch(self, positions, orientations=None, **kw) -> List[IKResult]:
        """:meth:`solve` for many targets: positions (N, 3), orientations (N, 4) or None."""
        positions = np.asarray(positions, dtype=float)
        if positions.ndim != 2 or positions.shape[1] != 3:
            raise InvalidGoal(f'positions must have shape (N, 3); got {positions.shape}')
        if orientations is not None:
            orientations = np.asarray(orientations, dtype=float)
            if orientations.shape != (len(positions), 4):
                raise InvalidGoal(f'orientations must have shape ({len(positions)}, 4); got '
                                  f'{orientations.shape}')
        return [self.solve(p, None if orientations is None else orientations[i], **kw)
                for i, p in enumerate(positions)]

    def candidate_indices(self, goal: str, pos: np.ndarray, rot, q_seed,
                          num_solutions: int = 16, refine: bool = True,
                          others: int = 0) -> np.ndarray:
        """Posture indices to decode: the seed's own index first, then far-apart table ones.

        ``others``: candidates coming from elsewhere (oriented postures), which count towards
        the ``candidates_per_solution`` per solution asked for.
        """
        return self.candidates(goal, pos, rot, q_seed, num_solutions, refine, others)[0]

    def candidates(self, goal: str, pos: np.ndarray, rot, q_seed, num_solutions: int = 16,
                   refine: bool = True, others: int = 0) -> Tuple[np.ndarray, np.ndarray]:
        """:meth:`candidate_indices` and the table row of each (-1: not from the table).

        The rows give :meth:`starting_postures` the table's decoded postures.
        """
        cfg = self.config
        count = max(cfg.num_candidates if goal == 'position' else cfg.pose_candidates,
                    math.ceil(cfg.candidates_per_solution * num_solutions) - others)
        if not refine:
            count = max(count, cfg.raw_candidates)
        table = self.models[goal].table
        rows = table.rows_near(pos, cfg.k_cells)
        pool = table.indices[rows]
        if pool.shape[1] == 1:
            # a 1-d index is a line: also sweep it over the range the table holds
            lo, hi = table.index_bounds
            pool = np.concatenate([pool, np.linspace(lo, hi, count)])
            rows = np.concatenate([rows, np.full(count, -1)])
        if q_seed is not None:
            z_seed = self.encode(goal, pos, rot, q_seed[None])[0]
            pool = np.concatenate([z_seed[None], pool])
            rows = np.concatenate([[-1], rows])
        pick = farthest_point_subset(pool, count)
        return pool[pick], rows[pick]

    def starting_postures(self, goal: str, pos: np.ndarray, rot, z: np.ndarray,
                          rows: np.ndarray) -> np.ndarray:
        """Postures (M, n) to refine from, for indices ``z`` from table ``rows`` (-1: none).

        Table rows take the table's decoded postures (when it keeps them and
        ``config.cached_postures``); the others are decoded at the goal.
        """
        postures = self.models[goal].table.postures
        if postures is None or not self.config.cached_postures:
            return self.decode(goal, pos, rot, z)
        cached = rows >= 0
        q = np.empty((len(z), self.robot.dof))
        # float32 storage: clip back onto the limits
        q[cached] = np.clip(postures[rows[cached]], self.robot.lower, self.robot.upper)
        if not cached.all():
            q[~cached] = self.decode(goal, pos, rot, z[~cached])
        return q

    def oriented_postures(self, pos: np.ndarray, rot: np.ndarray, count: int) -> np.ndarray:
        """Postures (M, n) for a pose goal from the position model's orientation-aware table.

        The position model's indices whose dataset rows had tip orientations nearest the goal
        keep those postures when decoded near the goal position (the table's decoded posture
        at the cell centre, or a decode at the goal); the last joint, free for a position goal,
        is then set in closed form to bring the tip orientation closest to the goal. Empty when
        the bundle has no position model or its table keeps no orientations.
        """
        gm = self.models.get('position')
        if gm is None or gm.table.orientations is None or count < 1:
            return np.empty((0, self.robot.dof))
        quat = Rotation.from_matrix(rot).as_quat()
        rows = gm.table.oriented_rows(pos, quat, count, self.config.oriented_cells)
        q = self.starting_postures('position', pos, None, gm.table.indices[rows], rows)
        return self.align_last_joint(q, rot)

    def align_last_joint(self, q: np.ndarray, rot: np.ndarray) -> np.ndarray:
        """``q`` with the last joint turned (within its limits) towards the orientation ``rot``.

        Every joint turns about its own z axis, so with ``a`` the last joint's frame at zero
        and ``B`` the fixed tip rotation, ``a Rz(t) B = rot`` is best met by the angle of
        ``Rz(t) ~ B R0^T rot B^T`` about z, where ``R0 = a B``.
        """
        q = q.copy()
        q[:, -1] = 0.0
        _, r0 = self.robot.fk_loop(q, self._data)
        b = self.robot.chain.tip_rotation
        m = b @ r0.transpose(0, 2, 1) @ rot @ b.T
        theta = np.arctan2(m[:, 1, 0] - m[:, 0, 1], m[:, 0, 0] + m[:, 1, 1])
        q[:, -1] = np.clip(theta, self.robot.lower[-1], self.robot.upper[-1])
        return q

    def _goal_net(self, goal: str, pos: np.ndarray, rot, rows: int) -> torch.Tensor:
        """The goal repeated ``rows`` times, in the network's normalised units."""
        g = make_goal(goal, np.repeat(pos[None], rows, 0),
                      None if rot is None else np.repeat(rot[None], rows, 0))
        return self.models[goal].norm.goal_to_net(torch.from_numpy(g.astype(np.float32)))

    @torch.no_grad()
    def decode(self, goal: str, pos: np.ndarray, rot, z: np.ndarray) -> np.ndarray:
        """Joint solutions (M, n) [rad] decoded from posture indices (M, latent), clipped."""
        gm = self.models[goal]
        g = self._goal_net(goal, pos, rot, len(z))
        x = gm.model.decode(g, torch.from_numpy(np.asarray(z, dtype=np.float32)))
        q = gm.norm.q_from_net(x).double().numpy()
        return np.clip(q, self.robot.lower, self.robot.upper)

    @torch.no_grad()
    def encode(self, goal: str, pos: np.ndarray, rot, q: np.ndarray) -> np.ndarray:
        """Posture indices (M, latent) of configurations (M, n) for a goal."""
        gm = self.models[goal]
        g = self._goal_net(goal, pos, rot, len(q))
        z, _ = gm.model.encode(g, gm.norm.q_to_net(torch.from_numpy(q.astype(np.float32))))
        return z.numpy().astype(np.float64)

    def errors(self, q: np.ndarray, pos: np.ndarray, rot) -> tuple:
        """Position errors [m] and orientation errors [rad] (zeros without ``rot``), (M,)."""
        p, r = self.robot.fk_loop(q, self._data) if len(q) <= 256 else self.robot.fk_rot(q)
        perr = np.linalg.norm(p - pos, axis=1)
        if rot is None:
            return perr, np.zeros(len(q))
        cos = (np.einsum('ij,nij->n', rot, r) - 1) / 2
        return perr, np.arccos(np.clip(cos, -1.0, 1.0))

    def refine(self, q: np.ndarray, pos: np.ndarray, rot, deadline: Optional[float] = None,
               iterations: Optional[int] = None, prune: bool = False,
               enough: Optional[int] = None):
        """Batched damped least squares towards the goal, within the joint limits.

        Sets ``self._cut_short`` when the deadline stopped it before convergence. With
        ``prune``, at the iterations in ``config.prune_at`` a candidate closer than
        ``config.prune_radius`` to one with a lower error (converged ones included) stops
        there: both are heading for the same solution, which the final duplicate removal would
        keep only once. Its row is returned as it was when it stopped. With ``enough``, it stops
        as soon as ``enough`` distinct rows meet the tolerances (the others are returned where
        they are, with their errors).

        Returns:
            refined configurations (M, n), position errors [m], orientation errors [rad].
        """
        cfg = self.config
        q = q.copy()
        n = len(q)
        rows = 3 if rot is None else 6
        lower, upper = self.robot.lower, self.robot.upper
        lam2 = cfg.damping ** 2
        eye = np.eye(rows)
        active = np.ones(n, dtype=bool)
        given_up = np.zeros(n, dtype=bool)
        perr_all, oerr_all = np.full(n, np.inf), np.zeros(n)
        stale = np.ones(n, dtype=bool)  # rows moved since their errors were computed
        score = np.full(n, np.inf)  # latest error of each row, to choose between neighbours
        window = cfg.stall_window
        history = np.full((window, n), np.inf)  # errors of the last ``window`` iterations
        exact = np.zeros(n, dtype=bool)
        goal = 'position' if rot is None else 'pose'
        self._cut_short = False
        for it in range(iterations or cfg.refine_iterations):
            if prune and it in cfg.prune_at:
                alive = np.flatnonzero(~given_up)
                order = alive[np.argsort(score[alive], kind='stable')]
                keep = self.distinct_mask(q[order], goal, cfg.prune_radius)
                active[order[~keep]] = False
            idx = np.flatnonzero(active)
            if len(idx) == 0:
                break
            if deadline is not None and time.perf_counter() > deadline:
                self._cut_short = True
                break
            p, r, jac = self.robot.jacobian_loop(q[idx], self._data)
            err = pos - p
            perr = np.sqrt((err * err).sum(1))
            done = perr < cfg.position_tolerance * 0.5
            stuck = perr > 10 * cfg.position_tolerance
            if rot is not None:
                rot_err = rotation_log(rot @ r.transpose(0, 2, 1))
                oerr = np.sqrt((rot_err * rot_err).sum(1))
                err = np.concatenate([err, rot_err], axis=1)
                done &= oerr < cfg.orientation_tolerance * 0.5
                stuck |= oerr > 10 * cfg.orientation_tolerance
                oerr_all[idx] = oerr
                score[idx] = perr + 0.1 * oerr
            else:
                score[idx] = perr
            perr_all[idx] = perr
            stale[idx] = False
            if enough and done.any():
                exact[idx[done]] = True
                found = np.flatnonzero(exact)
                if len(found) >= enough and self.distinct_mask(q[found], goal).sum() >= enough:
                    break
            if window and it >= max(window, cfg.stall_after):
                # far from the goal and hardly closer than ``window`` iterations ago: stalled
                stalled = stuck & (score[idx] > cfg.stall_ratio * history[it % window, idx])
            else:
                stalled = None
            if window:
                history[it % window, idx] = score[idx]
            if it >= cfg.give_up_after or (stalled is not None and stalled.any()):
                # far from the goal this late: a local minimum or a joint limit, not worth more
                if it < cfg.give_up_after:
                    stuck = stalled
                given_up[idx[stuck & ~done]] = True
                done |= stuck
            if done.any():
                active[idx[done]] = False
                go = ~done
                if not go.any():
                    continue
                idx, jac, err = idx[go], jac[go], err[go]
            j, e, qa = jac[:, :rows], err, q[idx]
            # joints at a limit that the descent direction J^T e pushes further out leave the
            # problem (active set)
            g = np.einsum('nrj,nr->nj', j, e)
            blocked = ((qa <= lower + 1e-9) & (g < 0)) | ((qa >= upper - 1e-9) & (g > 0))
            dq = self._dls_step(j * ~blocked[:, None, :], e, lam2, eye)
            scale = np.maximum(1.0, np.abs(dq).max(axis=1) / cfg.max_step)
            q[idx] = np.clip(qa + dq / scale[:, None], lower, upper)
            stale[idx] = True
        moved = np.flatnonzero(stale)
        if len(moved):
            perr_all[moved], oerr_all[moved] = self.errors(q[moved], pos, rot)
        return q, perr_all, oerr_all

    @staticmethod
    def _dls_step(j: np.ndarray, err: np.ndarray, lam2: float, eye: np.ndarray) -> np.ndarray:
        """Damped least squares steps J^T (J J^T + lambda^2 I)^-1 e for a batch."""
        jjt = j @ j.transpose(0, 2, 1) + lam2 * eye
        return (j.transpose(0, 2, 1) @ np.linalg.solve(jjt, err[..., None]))[..., 0]

    def _converged(self, perr, oerr, goal):
        ok = perr <= self.config.position_tolerance
        if goal == 'pose':
            ok &= oerr <= self.config.orientation_tolerance
        return ok

    def distinct_mask(self, q: np.ndarray, goal: str,
                      threshold: Optional[float] = None) -> np.ndarray:
        """Greedy keep-mask of rows at least ``threshold`` apart (default: the config's)."""
        threshold = self.config.distinct_threshold if threshold is None else threshold
        cols = slice(0, self.robot.dof - 1) if goal == 'position' else slice(None)
        near = cdist(q[:, cols], q[:, cols]) < threshold
        mask = np.zeros(len(q), dtype=bool)
        covered = np.zeros(len(q), dtype=bool)  # rows near an already kept one
        for i in range(len(q)):
            if not covered[i]:
                mask[i] = True
                covered |= near[i]
        return mask

    def _solve(self, pos, rot, goal, num, q_seed, obstacles, refine, objective, timeout, t0):
        deadline = None if timeout is None else t0 + timeout
        extra = self.oriented_postures(pos, rot, self.config.oriented_candidates) \
            if goal == 'pose' and refine else np.empty((0, self.robot.dof))
        z, rows = self.candidates(goal, pos, rot, q_seed, num, refine, len(extra))
        q = self.starting_postures(goal, pos, rot, z, rows) if refine else \
            self.decode(goal, pos, rot, z)
        if len(extra):
            # the seed's own posture first, then the oriented ones, then the pose model's
            head = 1 if q_seed is not None else 0
            q = np.concatenate([q[:head], extra, q[head:]])
            # their posture indices (the pose model's) are encoded once ranked, for the few kept
            z = np.concatenate([z[:head], np.full((len(extra), z.shape[1]), np.nan), z[head:]])
        timed_out = False
        # a goal far from every position in the data is out of reach: answer quickly
        far = self.models[goal].table.distance_to_data(pos) > self.config.reach_margin
        if refine:
            # decoded postures that nearly coincide would refine to the same solution
            near = self.distinct_mask(q, goal, self.config.distinct_threshold * 0.5)
            q, z = q[near], z[near]
            # ranked by the default objective, the first distinct exact solutions found are as
            # good as any: stop refining once there are enough
            enough = None if (q_seed is not None or obstacles or objective is not None
                              or self.config.early_stop_margin < 0) \
                else num + self.config.early_stop_margin
            q, perr, oerr = self.refine(q, pos, rot, deadline, 5 if far else None, prune=True,
                                        enough=enough)
            timed_out = self._cut_short
            if not far and not self._converged(perr, oerr, goal).any():
                q, z, perr, oerr = self._retry(goal, q, z, perr, oerr, pos, rot, deadline)
                timed_out = timed_out or self._cut_short
            if goal == 'pose' and not far and self.config.walk_rounds > 0:
                q, z, perr, oerr = self._walk(goal, q, z, perr, oerr, pos, rot, deadline,
                                              num + max(self.config.early_stop_margin, 0))
        else:
            perr, oerr = self.errors(q, pos, rot)
        conv = self._converged(perr, oerr, goal)
        if conv.any():  # with exact solutions, only exact ones are returned
            q, z, perr, oerr, conv = q[conv], z[conv], perr[conv], oerr[conv], conv[conv]
        # order: exact first, then by error; keep one solution per distinct posture
        order = np.lexsort((perr + oerr * 0.1, ~conv))
        q, z, perr, oerr, conv = q[order], z[order], perr[order], oerr[order], conv[order]
        keep = self.distinct_mask(q, goal)
        q, z, perr, oerr, conv = q[keep], z[keep], perr[keep], oerr[keep], conv[keep]
        sols = self._rank(q, z, perr, oerr, conv, q_seed, obstacles, objective, limit=num)
        self._fill_indices(goal, pos, rot, sols)
        if obstacles and refine and not any(s.converged and not s.in_collision for s in sols):
            extra = self.adjust_index(goal, pos, rot, sols, obstacles, deadline)
            if extra is not None:
                sols = self._merge(sols, extra, goal, q_seed, obstacles, objective)[:num]
        success = any(s.converged for s in sols)
        msg = '' if success else (
            'no solution within tolerance (best-effort solutions returned)' if sols else
            'no solution')
        return IKResult(success, sols, goal, timed_out, message=msg)

    def _walk(self, goal, q, z, perr, oerr, pos, rot, deadline, need: int):
        """More distinct exact solutions along the self-motion manifolds of the found ones."""
        cfg = self.config
        conv = self._converged(perr, oerr, goal)
        if not conv.any():
            return q, z, perr, oerr
        rows = np.flatnonzero(conv)
        rows = rows[np.argsort(perr[rows] + 0.1 * oerr[rows], kind='stable')]
        found = q[rows[self.distinct_mask(q[rows], goal)]]
        if len(found) >= need:
            return q, z, perr, oerr
        frontier, heading = found, None
        new_q, new_p, new_o = [], [], []
        for _ in range(cfg.walk_rounds):
            _, _, jac = self.robot.jacobian_loop(frontier, self._data)
            nvec = np.linalg.svd(jac)[2][:, -1]  # unit vectors spanning each null space
            if heading is None:
                nvec = np.concatenate([nvec, -nvec])
                frontier = np.concatenate([frontier, frontier])
            else:
                nvec *= np.where((nvec * heading).sum(1) < 0, -1.0, 1.0)[:, None]
            start = np.clip(frontier + cfg.walk_step * nvec, self.robot.lower, self.robot.upper)
            q2, p2, o2 = self.refine(start, pos, rot, deadline, cfg.walk_iterations)
            ok = self._converged(p2, o2, goal)
            if ok.any():
                far_enough = cdist(q2[ok], found).min(axis=1) >= cfg.distinct_threshold
                pick = np.flatnonzero(ok)[far_enough]
                pick = pick[self.distinct_mask(q2[pick], goal)]
            else:
                pick = np.empty(0, dtype=int)
            if len(pick) == 0:
                break
            new_q.append(q2[pick])
            new_p.append(p2[pick])
            new_o.append(o2[pick])
            found = np.concatenate([found, q2[pick]])
            frontier, heading = q2[pick], nvec[pick]
            if len(found) >= need:
                break
        if not new_q:
            return q, z, perr, oerr
        q2 = np.concatenate(new_q)
        return (np.concatenate([q, q2]),
                np.concatenate([z, np.full((len(q2), z.shape[1]), np.nan)]),
                np.concatenate([perr] + new_p), np.concatenate([oerr] + new_o))

    def _fill_indices(self, goal, pos, rot, sols: List[Solution]) -> None:
        """Posture indices of solutions that came without one: the encoding of their q."""
        todo = [s for s in sols if np.isnan(s.posture_index).any()]
        if todo:
            z = self.encode(goal, pos, rot, np.array([s.q for s in todo]))
            for s, zi in zip(todo, z):
                s.posture_index = zi.astype(np.float32)

    def _retry(self, goal, q, z, perr, oerr, pos, rot, deadline, keep: int = 8):
        """Restart the best candidates from perturbed configurations when none converged.

        The perturbations come from a random stream fixed per target, so answers stay
        deterministic.
        """
        best = np.argsort(perr + 0.1 * oerr)[:keep]
        rng = np.random.default_rng(zlib.crc32(pos.tobytes()))
        span = self.robot.upper - self.robot.lower
        q2 = np.concatenate([q[best] + rng.normal(0, 0.15, (len(best), q.shape[1])) * span,
                             rng.uniform(self.robot.lower, self.robot.upper, (keep, q.shape[1]))])
        q2 = np.clip(q2, self.robot.lower, self.robot.upper)
        q2, perr2, oerr2 = self.refine(q2, pos, rot, deadline)
        z2 = np.full((len(q2), z.shape[1]), np.nan)  # restarts: encoded once ranked
        return (np.concatenate([q, q2]), np.concatenate([z, z2]),
                np.concatenate([perr, perr2]), np.concatenate([oerr, oerr2]))

    def _rank(self, q, z, perr, oerr, conv, q_seed, obstacles, objective,
              limit: Optional[int] = None) -> List[Solution]:
        """Solutions ranked best first; with ``limit``, only the best ``limit`` of them.

        Self-collision is checked lazily in ranking order: a self-colliding posture drops
        behind every free one, so checking stops once ``limit`` free postures are found.
        """
        if len(q) == 0:
            return []
        clear = self.checker.clearance(q, obstacles)
        if objective is None:
            objective = SeedDistance(q_seed) if q_seed is not None else JointLimitMargin(
                self.robot)
        cost = np.asarray(objective(q), dtype=float)
        # tiers: free & exact < free & inexact < colliding & exact < colliding & inexact
        inexact_cost = np.where(conv, 0.0, (perr + oerr * 0.1) * 100.0)
        base = inexact_cost + np.where(conv, cost, 0.0) + 1e3 * (~conv)
        score = base + 2e3 * (clear <= 0.0)
        selfc = np.zeros(len(q), dtype=bool)
        limit = len(q) if limit is None else limit
        free = 0
        for i in np.argsort(score, kind='stable'):
            if free >= limit:
                break
            selfc[i] = self.checker.self_collision(q[i:i + 1])[0]
            free += not selfc[i]
        score = base + 2e3 * ((clear <= 0.0) | selfc)
        order = np.argsort(score, kind='stable')[:limit]
        return [Solution(q[i].copy(), float(perr[i]), float(oerr[i]), z[i].astype(np.float32),
                         float(score[i]), float(clear[i]), bool(selfc[i]), bool(conv[i]))
                for i in order]

    def _merge(self, sols, extra, goal, q_seed, obstacles, objective):
        q = np.array([s.q for s in sols + extra])
        z = np.array([s.posture_index for s in sols + extra])
        perr = np.array([s.position_error for s in sols + extra])
        oerr = np.array([s.orientation_error for s in sols + extra])
        conv = np.array([s.converged for s in sols + extra])
        order = np.lexsort((perr, ~conv))
        keep = order[self.distinct_mask(q[order], goal)]
        return self._rank(q[keep], z[keep], perr[keep], oerr[keep], conv[keep], q_seed,
                          obstacles, objective)

    def adjust_index(self, goal: str, pos: np.ndarray, rot, sols: List[Solution],
                     obstacles: Sequence[Obstacle], deadline=None,
                     step: float = 0.25) -> Optional[List[Solution]]:
        """Algorithm 2: move posture indices element by element while clearance improves.

        Starts from the best colliding solutions; each trial decodes and refines a neighbour
        index; stops at a collision-free exact solution or when the budget is spent.
        """
        cfg = self.config
        starts = [s for s in sols if s.converged][:3] or sols[:3]
        budget = cfg.adjust_budget
        found: List[Solution] = []
        lo, hi = self.models[goal].table.index_bounds
        for s in starts:
            z = s.posture_index.astype(np.float64)
            best = s.min_obstacle_distance
            while budget > 0:
                trials = []
                for d in range(len(z)):
                    for sign in (1.0, -1.0):
                        t = z.copy()
                        t[d] = np.clip(t[d] + sign * step * (hi[d] - lo[d]), lo[d], hi[d])
                        trials.append(t)
                trials = np.array(trials)
                budget -= len(trials)
                q, perr, oerr = self.refine(self.decode(goal, pos, rot, trials), pos, rot,
                                            deadline)
                conv = self._converged(perr, oerr, goal)
                clear = self.checker.clearance(q, obstacles)
                clear = np.where(self.checker.self_collision(q) | ~conv, -np.inf, clear)
                i = int(np.argmax(clear))
                if clear[i] <= best:
                    break
                best, z = clear[i], trials[i]
                found.append(Solution(q[i], float(perr[i]), float(oerr[i]),
                                      trials[i].astype(np.float32), 0.0, float(clear[i]),
                                      False, True))
                if best > 0:
                    break
            if found and found[-1].min_obstacle_distance > 0:
                break
        return found or None


def result_to_dict(res: IKResult, joint_names: Sequence[str]) -> Dict:
    """A JSON-ready view of a result (for ``sik-solve --json``)."""
    return {
        'success': res.success, 'goal': res.goal, 'timed_out': res.timed_out,
        'elapsed_s': res.elapsed, 'message': res.message, 'joint_names': list(joint_names),
        'solutions': [{
            'q': s.q.tolist(), 'position_error': s.position_error,
            'orientation_error': s.orientation_error,
            'posture_index': [float(v) for v in s.posture_index], 'score': s.score,
            'min_obstacle_distance': (None if not np.isfinite(s.min_obstacle_distance)
                                      else s.min_obstacle_distance),
            'self_collision': s.self_collision, 'converged': s.converged,
        } for s in res.solutions],
    }


def dumps(res: IKResult, joint_names: Sequence[str]) -> str:
    """:func:`result_to_dict` as a JSON string."""
    return json.dumps(result_to_dict(res, joint_names), indent=2)
