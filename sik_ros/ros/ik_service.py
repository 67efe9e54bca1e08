"""``~/solve_ik`` and ``~/goal``: one IK request, from message to library call to answer.

:func:`solve_request` checks every field of a ``SolveIK`` request at the edge (frame, goal, seed,
obstacles, timeout), solves it with the node's solvers and returns an :class:`Answer`: the code,
message, library result and goal. It is two steps, which ``~/solve_ik_batch``
(:mod:`~sik_ros.ros.batch_service`) takes apart: :func:`solve_options` checks what a request asks
besides its goal (solution count, seed, obstacles, timeout), :func:`solve_goal` solves one
goal with them. :func:`checked_goal` is the one check of a goal's pose (``~/solve_ik`` targets,
``~/solve_ik_batch`` targets and ``~/goal`` goals); :func:`fill_answer` puts an answer's ranked
solutions into a message as ``IKSolution`` messages (:func:`solution_msgs`);
:func:`solver_settings` gives the solver fields the node's parameters set. Bad input raises a
:class:`~sik_ros.errors.SikError` that :class:`~sik_ros.ros.guard.RequestGuard` turns into its
code.
"""

from dataclasses import dataclass
from typing import Callable, List, Optional, Sequence, Tuple

import numpy as np
from std_msgs.msg import Header

from sik_interfaces.srv import SolveIK
from sik_ros.errors import InvalidFrame
from sik_ros.kinematics.collision import Obstacle
from sik_ros.ros import conversions as conv
from sik_ros.ros.params import NodeParams
from sik_ros.serving.solvers import Solver
from sik_ros.solver import IKResult

R = SolveIK.Response


@dataclass(frozen=True)
class Arm:
    """What the services need to know of the served arm.

    Attributes:
        base_frame: the frame goals are given in.
        joint_names: the arm's joints, in chain order.
    """

    base_frame: str
    joint_names: Sequence[str]

    def check_frame(self, frame_id: str, what: str) -> None:
        """Raise :class:`InvalidFrame` unless ``frame_id`` is the base frame or empty."""
        if frame_id.lstrip('/') not in ('', self.base_frame):
            raise InvalidFrame(f'{what} frame_id {frame_id!r} is not the base frame '
                               f'{self.base_frame!r} (or empty); sik_node does not transform '
                               f'frames')


def solver_settings(p: NodeParams) -> dict:
    """The :class:`~sik_ros.solver.SolverConfig` fields that node parameters set."""
    return {'position_tolerance': p.position_tolerance,
            'orientation_tolerance': p.orientation_tolerance,
            'max_solutions_cap': p.max_solutions_cap, 'max_obstacles': p.max_obstacles,
            'max_waypoints': p.max_waypoints, 'one_per_family': p.one_per_family}


@dataclass(frozen=True)
class Answer:
    """What one goal got (a ``SolveIK`` request, or a target of a ``SolveIKBatch``).

    Attributes:
        code: the response's error code.
        message: the response's message.
        result: the library's result.
        position: the goal position [m].
        orientation: the goal quaternion x y z w, or None for a position goal.
    """

    code: int
    message: str
    result: IKResult
    position: np.ndarray
    orientation: Optional[np.ndarray]


@dataclass(frozen=True)
class SolveOptions:
    """What a ``SolveIK`` or ``SolveIKBatch`` request asks besides its goals, checked.

    Attributes:
        num_solutions: solutions to return per goal.
        note: a remark for the answer's message (a clamped ``max_solutions``), or empty.
        seed: the seed (n,) [rad] in the arm's joint order, or None.
        obstacles: the obstacles in the base frame.
        timeout: each goal's budget [s].
    """

    num_solutions: int
    note: str
    seed: Optional[np.ndarray]
    obstacles: List[Obstacle]
    timeout: float


def solve_options(arm: Arm, request, p: NodeParams,
                  state_seed: Callable[[], Optional[np.ndarray]]) -> SolveOptions:
    """The checked ``max_solutions``, seed, obstacles and timeout of a request.

    Args:
        arm: the served arm.
        request: a ``SolveIK`` or ``SolveIKBatch`` request (any field may be hostile).
        p: the parameters in force.
        state_seed: the latest ``joint_states`` as a seed (or None), used when the request
            gives none and ``use_joint_states`` is on.

    Raises:
        InvalidSeed, InvalidGoal: the seed's names, the obstacles or the timeout. The seed's
            values are checked by the solver (or by :func:`~sik_ros.solver.inputs.check_seed`).
    """
    num, note = conv.solution_count(request.max_solutions, p.num_solutions, p.max_solutions_cap)
    seed = conv.seed_from_joint_state(request.seed, arm.joint_names)
    if seed is None and p.use_joint_states:
        seed = state_seed()
    obstacles = conv.obstacles_from_msgs(request.obstacles, request.obstacle_poses,
                                         p.max_obstacles)
    timeout = conv.seconds_from_duration(request.timeout) or p.timeout
    return SolveOptions(num, note, seed, obstacles, timeout)


def solve_goal(solvers: Solver, position: np.ndarray, orientation: Optional[np.ndarray],
               options: SolveOptions, p: NodeParams) -> Answer:
    """Solve one checked goal with a request's options: its code, message, result and goal.

    Raises:
        SikError: bad input the solver finds (a non-finite goal, a zero quaternion, a seed
            outside the limits), or no solver free in time.
    """
    result = solvers.solve(position, orientation, options.num_solutions, seed=options.seed,
                           obstacles=options.obstacles, refine=p.refine,
                           timeout=options.timeout)
    code, text = conv.result_code(result, bool(options.obstacles), options.timeout)
    return Answer(code, '; '.join(t for t in (text, options.note) if t), result, position,
                  orientation)


def solve_request(solvers: Solver, arm: Arm, request: SolveIK.Request, p: NodeParams,
                  state_seed: Callable[[], Optional[np.ndarray]]) -> Answer:
    """Solve a ``SolveIK`` request: its code, message, library result and goal.

    Args:
        solvers: where to solve.
        arm: the served arm.
        request: the request (any field may be hostile).
        p: the parameters in force.
        state_seed: the latest ``joint_states`` as a seed (or None), used when the request
            gives none and ``use_joint_states`` is on.

    Raises:
        SikError: bad input (its code: :func:`~sik_ros.ros.conversions.error_code_for`), or no
            solver free in time.
    """
    position, orientation = checked_goal(arm, request.target, request.use_orientation, 'target')
    options = solve_options(arm, request, p, state_seed)
    return solve_goal(solvers, position, orientation, options, p)


def checked_goal(arm: Arm, target, use_orientation: bool, what: str
                 ) -> Tuple[np.ndarray, Optional[np.ndarray]]:
    """A goal (a ``PoseStamped``) checked: in the arm's base frame, finite, a unit quaternion.

    The one check of ``~/solve_ik`` targets and ``~/goal`` goals.

    Returns:
        the position [m] and the quaternion x y z w (None for a position goal).

    Raises:
        InvalidFrame, InvalidGoal: another frame, or a bad pose (naming ``what``).
    """
    arm.check_frame(target.header.frame_id, what)
    return conv.goal_from_pose(target.pose, use_orientation)


def solution_msgs(result: IKResult, arm: Arm, header: Header) -> list:
    """The ranked solutions of a result as ``IKSolution`` messages."""
    return conv.solution_msgs(result.solutions, arm.joint_names, header)


def fill_answer(msg, answer: Answer, arm: Arm, header: Header) -> None:
    """Set ``msg.solutions`` and ``msg.num_families`` from an answer.

    ``msg``: a ``SolveIK`` response or a ``SolveIKResult`` (the code and message are the
    caller's to set).
    """
    msg.solutions = solution_msgs(answer.result, arm, header)
    msg.num_families = int(answer.result.num_families)
