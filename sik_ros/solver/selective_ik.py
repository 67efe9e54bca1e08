"""The solver's front: :class:`SelectiveIK` loads a bundle, checks input, runs the stages.

Each call checks its arguments (:mod:`~sik_ros.solver.inputs`), then hands the goal to the
stage functions (:mod:`~sik_ros.solver.pipeline` for one target, :mod:`~sik_ros.solver.path`
for a Cartesian path) with the solver's :class:`~sik_ros.solver.context.Context`.
"""

from dataclasses import fields, replace
from pathlib import Path
import threading
import time
from typing import Dict, List, Optional, Sequence, Union

import numpy as np

from sik_ros.bundles.bundle import GoalModel, load_bundle
from sik_ros.deadline import Deadline
from sik_ros.errors import InvalidArgument, ModelNotReady
from sik_ros.kinematics.collision import CollisionChecker, Obstacle
from sik_ros.kinematics.robot import Robot
from sik_ros.solver import parallel as _parallel, path as _path, pipeline
from sik_ros.solver.config import PATH_DEFAULTS, SolverConfig
from sik_ros.solver.context import Context
from sik_ros.solver.inputs import (check_goal, check_num_solutions,
                                   check_objective, check_obstacles, check_path, check_seed)
from sik_ros.solver.objectives import Objective
from sik_ros.solver.path import PathResult, PathSettings
from sik_ros.solver.results import IKResult
from sik_ros.validation import flag, positive, seconds, vector

__all__ = ['SelectiveIK']


class SelectiveIK:
    """Multi-solution IK from trained SIK models and their posture-index tables.

    Not thread-safe per instance (Pinocchio data); :meth:`clone` gives an instance sharing the
    models and tables for another thread. Calls on one instance are serialised by a lock.
    """

    def __init__(self, robot: Robot, models: Dict[str, GoalModel],
                 config: Optional[SolverConfig] = None, bundle: Optional[Path] = None):
        self.robot = robot
        self.models = models
        self.config = config or SolverConfig()
        self.bundle = bundle
        self.checker = CollisionChecker(robot)
        self._lock = threading.Lock()
        self._ctx = Context(robot, models, self.config, robot.model.createData(), self.checker)

    # -- loading ---------------------------------------------------------------------------------

    @classmethod
    def load(cls, bundle: Union[str, Path] = 'panda',
             config: Optional[SolverConfig] = None) -> 'SelectiveIK':
        """Load a bundle: a name of the bundled models (``panda``) or a bundle directory.

        Raises:
            CorruptArtifact: a missing or damaged file.
            ArtifactMismatch: files made for another robot or model.
        """
        if not isinstance(bundle, (str, Path)):
            raise InvalidArgument(f'bundle must be a bundled name or a directory; got {bundle!r}')
        path, robot, models = load_bundle(bundle)
        return cls(robot, models, config, path)

    def clone(self) -> 'SelectiveIK':
        """An instance sharing models and tables, with its own Pinocchio/coal data."""
        return SelectiveIK(self.robot, self.models, self.config, self.bundle)

    def with_config(self, **changes) -> 'SelectiveIK':
        """An instance with some :class:`SolverConfig` fields changed.

        Raises:
            InvalidArgument: an unknown field or a bad value.
        """
        return SelectiveIK(self.robot, self.models, self._changed(changes), self.bundle)

    def configure(self, **changes) -> 'SelectiveIK':
        """Change some :class:`SolverConfig` fields of this instance, in place; returns it.

        Unlike :meth:`with_config`, the instance keeps its Pinocchio data and collision
        checker (no geometry is loaded again): for a pool whose instances follow parameter
        changes. Calls already running finish with the old settings.

        Raises:
            InvalidArgument: an unknown field or a bad value.
        """
        config = self._changed(changes)
        with self._lock:
            self.config = config
            self._ctx = replace(self._ctx, config=config)
        return self

    def _changed(self, changes: Dict) -> SolverConfig:
        unknown = sorted(set(changes) - {f.name for f in fields(SolverConfig)})
        if unknown:
            raise InvalidArgument(f'unknown SolverConfig fields {unknown}')
        return replace(self.config, **changes)

    def warm_up(self) -> float:
        """Solve one of each kind of request once.

        Position and pose goals: one solution, several (the family search's parts), an
        obstacle, a short path.

        The first calls of an instance allocate its working memory (and the first of a process
        its allocator arenas): a server warms its solvers before it accepts requests, so that
        neither the first answers' latency nor the memory measured afterwards carries that.

        Returns:
            the time it took [s].
        """
        t0 = time.perf_counter()
        q = 0.5 * (self.robot.lower + self.robot.upper)
        pos, quat = self.fk(q)
        ball = Obstacle('sphere', (0.05,), position=tuple(pos + 0.3))
        for goal in self.goals:
            rot = quat if goal == 'pose' else None
            self.solve(pos, rot, seed=q, timeout=1.0)
            self.solve(pos, rot, num_solutions=2, timeout=1.0)  # the family search's parts
            self.solve(pos, rot, obstacles=[ball], timeout=1.0)
            line = pos + np.linspace(0.0, 0.02, 3)[:, None] * [0.0, 0.0, 1.0]
            self.solve_path(line, None if rot is None else np.repeat(quat[None], 3, 0), seed=q,
                            timeout=1.0)
        return time.perf_counter() - t0

    # -- what it is ------------------------------------------------------------------------------

    @property
    def context(self) -> Context:
        """The parts every stage function takes (read-only): robot, models, config, data.

        For studies and benchmarks that call the stages
        (:mod:`~sik_ros.solver.candidates`, :mod:`~sik_ros.solver.codec`,
        :mod:`~sik_ros.solver.refine`, :mod:`~sik_ros.solver.ranking`,
        :mod:`~sik_ros.solver.adjust`) on their own. Its Pinocchio data is this instance's:
        not for another thread.
        """
        return self._ctx

    @property
    def joint_names(self) -> List[str]:
        """Arm joint names, in the order of every ``q``."""
        return list(self.robot.joint_names)

    @property
    def learned(self) -> bool:
        """Whether a learned model answers (False: a table of configurations alone)."""
        return all(gm.model is not None for gm in self.models.values())

    @property
    def goals(self) -> List[str]:
        """Goal kinds this bundle answers (``position``, ``pose``)."""
        return sorted(self.models)

    def fk(self, q: np.ndarray):
        """Tip position (3,) [m] and quaternion (4,) x y z w of a configuration (n,)."""
        return self.robot.fk(vector(q, self.robot.dof, 'q'))

    def check_seed(self, seed) -> np.ndarray:
        """A seed as a (n,) array, or :class:`InvalidSeed` saying what is wrong with it."""
        return check_seed(self.robot, seed)

    # -- solving ---------------------------------------------------------------------------------

    def solve(self, position, orientation=None, num_solutions: int = 16, seed=None,
              obstacles: Sequence[Obstacle] = (), refine: bool = True,
              objective: Optional[Objective] = None, timeout: Optional[float] = None,
              one_per_family: Optional[bool] = None) -> IKResult:
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
            one_per_family: at most one solution per posture family, the best of each
                (``Solution.family``); None: the config's ``one_per_family``.

        Raises:
            InvalidGoal, InvalidSeed, InvalidArgument: bad input (see docs/interfaces.md).
            ModelNotReady: ``refine`` False with no learned model (a table of
                configurations, :mod:`~sik_ros.bundles.sweep_models`).
        """
        t0 = time.perf_counter()
        goal = check_goal(position, orientation, self.goals)
        num = check_num_solutions(num_solutions, self.config.max_solutions_cap)
        q_seed = None if seed is None else check_seed(self.robot, seed)
        obstacles = check_obstacles(obstacles, self.config.max_obstacles)
        objective = check_objective(objective)
        refine = flag(refine, 'refine')
        if not refine and not self.learned:
            raise ModelNotReady('raw answers (refine=False) are the learned model\'s, and no '
                                'learned model serves this arm yet (its table of '
                                'configurations answers refined requests)')
        timeout = seconds(timeout, 'timeout')
        per_family = None if one_per_family is None else flag(one_per_family,
                                                              'one_per_family')
        deadline = Deadline.after(timeout, t0)
        with self._lock:
            result = pipeline.solve(self._ctx, goal, num, q_seed, obstacles, refine, objective,
                                    deadline, one_per_family=per_family)
        result.elapsed = time.perf_counter() - t0
        return result

    def solve_batch(self, positions, orientations=None, *, num_solutions: int = 16, seed=None,
                    obstacles: Sequence[Obstacle] = (), timeout: Optional[float] = None,
                    workers: Optional[int] = None, progress: bool = False,
                    executor=None, **kw) -> List[IKResult]:
        """:meth:`solve` for many targets, on several cores: one result per target, in order.

        Each answer is the one :meth:`solve` gives for its row. The rows go in chunks to
        ``workers`` processes, each holding one solver for the whole batch (forked from this
        one, or, in a process running ``rclpy``, loading the bundle once); a small batch, or
        ``workers=1``, is solved in this process. With an ``executor``
        (:class:`~sik_ros.solver.cluster.RayExecutor`) the chunks go to its workers instead,
        on a Ray cluster.

        Args:
            positions: targets (N, 3) [m] in the base frame.
            orientations: None for position goals; else (N, 4) quaternions x y z w.
            num_solutions: most solutions per target.
            seed: None, one configuration (n,) for every target, or one per target (N, n)
                [rad].
            obstacles: :class:`Obstacle` list, for every target.
            timeout: each target's budget [s].
            workers: processes (None: every core this process may run on).
            progress: show a tqdm progress bar on stderr.
            executor: None (this machine's processes), or a
                :class:`~sik_ros.solver.cluster.RayExecutor` (``workers`` is then its own).
            **kw: :meth:`solve`'s other keywords (``refine``, ``objective``,
                ``one_per_family``).

        Raises:
            InvalidGoal, InvalidSeed, InvalidArgument: a bad row (the error :meth:`solve`
                raises for it, its message starting with ``target i:``, its ``row``
                attribute ``i``) or a bad keyword; nothing is solved then.
        """
        pos, quat, seeds = _parallel.check_rows(self, positions, orientations, seed)
        given = dict(num_solutions=check_num_solutions(num_solutions,
                                                       self.config.max_solutions_cap),
                     obstacles=check_obstacles(obstacles, self.config.max_obstacles),
                     timeout=seconds(timeout, 'timeout'), **kw)
        unknown = sorted(set(kw) - {'refine', 'objective', 'one_per_family'})
        if unknown:
            raise InvalidArgument(f'solve_batch got unknown keywords {unknown}')
        if 'objective' in kw:
            check_objective(kw['objective'])
        if executor is not None and not callable(getattr(executor, 'solve_chunks', None)):
            raise InvalidArgument(f'executor must be a RayExecutor (or have its solve_chunks); '
                                  f'got {type(executor).__name__}')
        return _parallel.solve_rows(self, pos, quat, seeds, given,
                                    _parallel.check_workers(workers), flag(progress, 'progress'),
                                    executor)

    def solve_path(self, positions, orientations=None, seed=None,
                   num_paths: int = PATH_DEFAULTS.num_paths,
                   max_joint_step: float = PATH_DEFAULTS.max_joint_step,
                   obstacles: Sequence[Obstacle] = (), timeout: Optional[float] = None,
                   path_tolerance: float = PATH_DEFAULTS.path_tolerance) -> PathResult:
        """Ranked joint paths through Cartesian waypoints, without flips.

        Args:
            positions: waypoints (N, 3) [m] in the base frame.
            orientations: None for position goals; else (N, 4) quaternions x y z w.
            seed: current joint configuration (n,) [rad]: paths starting near it rank first.
            num_paths: most paths returned (each from a distinct start).
            max_joint_step: largest joint change between consecutive waypoints [rad].
            obstacles: :class:`Obstacle` list; no configuration of a path touches one.
            timeout: budget of the whole path [s].
            path_tolerance: how far the tool may leave the straight segment between two
                waypoints [m] (checked at interpolated configurations).

        Raises:
            InvalidGoal, InvalidSeed, InvalidArgument: bad input (see docs/interfaces.md).
        """
        t0 = time.perf_counter()
        goals = check_path(positions, orientations, self.goals, self.config.max_waypoints)
        q_seed = None if seed is None else check_seed(self.robot, seed)
        obstacles = check_obstacles(obstacles, self.config.max_obstacles)
        given = dict(num_paths=check_num_solutions(num_paths, self.config.max_solutions_cap,
                                                   'num_paths'),
                     max_joint_step=positive(max_joint_step, 'max_joint_step'),
                     path_tolerance=positive(path_tolerance, 'path_tolerance'))
        pose = orientations is not None
        settings = PathSettings.for_paths(pose, **given)
        # a position path that fails with its narrow beam is planned again with the wide one,
        # from starts spread over the postures
        wider = None if pose else PathSettings.for_paths(True, near_seed=False, **given)
        timeout = seconds(timeout, 'timeout')
        deadline = Deadline.after(timeout, t0)
        with self._lock:
            result = _path.solve_path(self._ctx, goals, q_seed, obstacles, settings, deadline,
                                      wider)
        result.elapsed = time.perf_counter() - t0
        return result
