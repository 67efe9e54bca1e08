"""``/compute_ik`` and ``/compute_fk``: MoveIt's kinematics services, answered by sik_node.

Clients written for move_group (``moveit_msgs/srv/GetPositionIK`` and ``GetPositionFK``, e.g.
pymoveit2 or MoveIt's own ``MoveGroupInterface`` helpers) get their answers from the node's
solvers unchanged. A request goes through the node's
:class:`~sik_ros.ros.guard.RequestGuard` (refusals, counting, any error into a code) and the
same :class:`~sik_ros.serving.solvers.Solver` as ``~/solve_ik``; the MoveIt specifics are here
and in :mod:`~sik_ros.ros.moveit_conversions`.

``/compute_ik``: the group must be the node's (``ik_group``), the link the tip or one fixed to
it, the pose's frame the base or one fixed to it; the robot state seeds the solve; joint
constraints bound the answer (they rank the solutions too), position and orientation
constraints and ``avoid_collisions`` are checked on it; the timeout counts to the nanosecond (0:
the node's ``timeout``). The answer is the best-ranked exact solution that meets them all (the
one nearest the seed by default): the request's joints as given with the arm's set.
docs/interfaces.md lists the codes.
"""

import time
from typing import Callable, Optional, Tuple

import numpy as np
from std_msgs.msg import Header

from sik_interfaces.srv import SolveIK
from sik_ros.kinematics.link_frames import LinkFrames
from sik_ros.ros import conversions as conv
from sik_ros.solver import IKResult, Solution
from sik_ros.solver.goal_constraints import GoalConstraints, JointRangeCost

try:  # moveit_msgs: MoveIt's own where installed, else sik_ros's copy (scripts/setup.sh)
    from geometry_msgs.msg import PoseStamped
    from moveit_msgs.msg import MoveItErrorCodes as E
    from moveit_msgs.srv import GetPositionFK, GetPositionIK
    from sik_ros.ros import moveit_conversions as mc
    MISSING: Optional[str] = None
except ImportError as exc:  # the node serves without these two services
    MISSING = str(exc)

R = SolveIK.Response
#: ``source`` of every error code the services send.
SOURCE = 'sik_node'
#: Most further solves of one request when its first answers do not qualify.
ROUNDS = 8


def default_group(robot) -> str:
    """The group a bundle answers when ``ik_group`` is empty: ``<robot name>_arm``."""
    return f'{robot.name}_arm'


class _Outcome:
    """What the guard fills: a ``SolveIK`` code (for the statistics), a message, MoveIt's code."""

    def __init__(self):
        self.error_code, self.message = R.INTERNAL_ERROR, ''
        self.moveit: Optional[int] = None


class MoveItServices:
    """``/compute_ik`` and ``/compute_fk`` of one node."""

    def __init__(self, node, group, qos):
        """Create both services on ``node`` (names from its parameters)."""
        self._node = node
        self._frames: Optional[Tuple[object, LinkFrames]] = None
        p = node.params
        node.create_service(GetPositionIK, p.compute_ik_service, self.compute_ik,
                            qos_profile=qos, callback_group=group)
        node.create_service(GetPositionFK, p.compute_fk_service, self.compute_fk,
                            qos_profile=qos, callback_group=group)

    # -- the services ----------------------------------------------------------------------------

    def compute_ik(self, request, response):
        """Answer a ``GetPositionIK`` request (never raises)."""
        return self._answer('compute_ik', response, lambda: self._ik(request.ik_request,
                                                                     response))

    def compute_fk(self, request, response):
        """Answer a ``GetPositionFK`` request (never raises)."""
        return self._answer('compute_fk', response, lambda: self._fk(request, response))

    def _answer(self, where: str, response, solve):
        def fill(outcome: _Outcome):
            try:
                code, message = solve()
            except mc.MoveItRefusal as exc:
                code, message = exc.code, str(exc)
            outcome.moveit = code
            return mc.STATISTICS_CODES.get(code, R.INVALID_GOAL), message

        outcome = self._node.guard.answer(where, _Outcome(), fill)
        code = outcome.moveit if outcome.moveit is not None else mc.moveit_code(
            outcome.error_code)
        if code != E.SUCCESS:
            response = type(response)()
        response.error_code = E(val=int(code), message=str(outcome.message), source=SOURCE)
        return response

    # -- IK --------------------------------------------------------------------------------------

    def _ik(self, req, response) -> Tuple[int, str]:
        node = self._node
        ik, arm, solvers, p = node.ik, node.arm, node.solvers, node.params
        if ik is None or arm is None or solvers is None:
            return E.FAILURE, 'sik_node has no bundle loaded'
        group = p.ik_group or default_group(ik.robot)
        if req.group_name != group:
            raise mc.MoveItRefusal(E.INVALID_GROUP_NAME, f'group_name {req.group_name!r} is '
                                   f'not sik_node\'s group {group!r} (parameter ik_group)')
        given = mc.given_state(req.robot_state)
        seed = mc.arm_values(given, arm.joint_names, self._current())
        frames = self._link_frames(ik.robot)
        link, target = self._target(req, ik.robot.tip_frame)
        position, quat = mc.tip_goal(frames, target.pose, target.header.frame_id, link)
        rules = mc.goal_constraints(req.constraints, arm.joint_names, frames, given)
        timeout = conv.seconds_from_duration(req.timeout) or p.timeout
        robot = ik.robot
        if seed is not None:  # a seed is a hint: one outside the limits is moved inside
            seed = np.clip(seed, robot.lower, robot.upper)
        code, message, best = search(
            lambda num, start, objective, seconds: solvers.solve(
                position, quat, num, seed=start, refine=p.refine, timeout=seconds,
                objective=objective),
            seed, rules, robot, p.num_solutions, timeout,
            lambda result: pick(result, rules, bool(req.avoid_collisions), arm.joint_names,
                                frames, given.values(), timeout))
        if best is not None:
            response.solution = mc.solution_state(given, arm.joint_names, best.q,
                                                  self._header(arm.base_frame),
                                                  req.robot_state)
        return code, message

    @staticmethod
    def _target(req, tip: str):
        """The link and stamped pose of a request (one tip: several are refused)."""
        poses, links = req.pose_stamped_vector, list(req.ik_link_names)
        if len(poses) > 1 or len(links) > 1:
            raise mc.MoveItRefusal(E.INVALID_LINK_NAME, f'sik_node\'s group has one tip '
                                   f'({tip}); got {len(poses)} poses in pose_stamped_vector '
                                   f'and {len(links)} ik_link_names')
        link = links[0] if links else ('' if len(poses) else req.ik_link_name)
        return link, (poses[0] if len(poses) else req.pose_stamped)

    # -- FK --------------------------------------------------------------------------------------

    def _fk(self, req, response) -> Tuple[int, str]:
        node = self._node
        ik, arm = node.ik, node.arm
        if ik is None or arm is None:
            return E.FAILURE, 'sik_node has no bundle loaded'
        frames = self._link_frames(ik.robot)
        frame = mc.frame_in_base(frames, req.header.frame_id, 'header')
        links = list(req.fk_link_names)
        if len(links) > mc.MAX_STATE_JOINTS:
            raise mc.MoveItRefusal(E.INVALID_LINK_NAME, f'{len(links)} fk_link_names; at most '
                                   f'{mc.MAX_STATE_JOINTS} are accepted')
        unknown = [name for name in links if not frames.placeable(name)]
        if unknown:
            known = frames.base_fixed + frames.moving
            raise mc.MoveItRefusal(E.INVALID_LINK_NAME, f'links {unknown[:10]} are not placed '
                                   f'by the arm\'s joints (these are: {known})')
        q = mc.arm_values(mc.given_state(req.robot_state), arm.joint_names, self._current())
        if q is None:
            raise mc.MoveItRefusal(E.INVALID_ROBOT_STATE, 'robot_state gives no arm joint (and '
                                   'no joint_states were received)')
        header = self._header(req.header.frame_id or arm.base_frame)
        inverse = frame.inverse()
        response.pose_stamped = [PoseStamped(header=header, pose=mc.pose_of(inverse @ placed))
                                 for placed in frames.poses(q, links)]
        response.fk_link_names = links
        return E.SUCCESS, f'{len(links)} link poses'

    # -- shared ----------------------------------------------------------------------------------

    def _current(self):
        """The latest ``joint_states`` (None when none came or the tap is off)."""
        return self._node.joint_states.latest()[0]

    def _header(self, frame_id: str) -> Header:
        return Header(stamp=self._node.get_clock().now().to_msg(), frame_id=frame_id)

    def _link_frames(self, robot) -> LinkFrames:
        """The links of the loaded robot (made again when the bundle changes)."""
        cached = self._frames
        if cached is None or cached[0] is not robot:
            cached = self._frames = (robot, LinkFrames(robot))
        return cached[1]


def search(solve: Callable, seed: Optional[np.ndarray], rules: GoalConstraints, robot,
           num_solutions: int, timeout: float, judge: Callable
           ) -> Tuple[int, str, Optional[Solution]]:
    """Solve until an answer meets the request, or the time runs out: code, message, answer.

    The first call asks for one solution (the fast path of ``~/solve_ik``) when nothing is
    constrained, else for ``num_solutions`` ranked by :class:`JointRangeCost` (distance from
    the seed, moved into the joint ranges, plus a steep cost outside them). When exact
    solutions were found but none qualifies, it asks again: for ``num_solutions`` when it asked
    for one, then, with joint ranges, from the exact solution nearest them clipped into them (a
    redundant arm's solution then moves into the ranges), at most :data:`ROUNDS` times.

    Args:
        solve: ``solve(num, seed, objective, seconds)`` -> :class:`IKResult`.
        seed: the request's seed (n,) [rad] within the limits, or None.
        rules: the request's constraints.
        robot: the arm (its limits).
        num_solutions: solutions asked for beyond the first call.
        timeout: the whole budget [s].
        judge: ``judge(result)`` -> ``(code, message, solution or None)`` (:func:`pick`).
    """
    end = time.monotonic() + timeout
    lo, hi = np.maximum(rules.lower, robot.lower), np.minimum(rules.upper, robot.upper)
    ranges = rules.bounds_joints and bool(np.all(lo <= hi))
    num, objective = 1, None
    if not rules.empty:
        num = num_solutions
    if rules.bounds_joints:
        if seed is not None and ranges:
            seed = np.clip(seed, lo, hi)
        objective = JointRangeCost(seed, rules.lower, rules.upper)
    result = solve(num, seed, objective, timeout)
    first = code, message, best = judge(result)
    cost = JointRangeCost(None, rules.lower, rules.upper)
    for _ in range(ROUNDS):
        left = end - time.monotonic()
        exact = [s for s in result.solutions if s.converged]
        if best is not None or left <= 0 or not exact:
            break
        if num < num_solutions:
            num = num_solutions
        elif ranges:
            nearest = exact[int(np.argmin(cost(np.array([s.q for s in exact]))))]
            num, seed, objective = 1, np.clip(nearest.q, lo, hi), None
        else:
            break
        result = solve(num, seed, objective, left)
        code, message, best = judge(result)
    return (code, message, best) if best is not None else first


def pick(result: IKResult, rules: GoalConstraints, avoid_collisions: bool, joint_names,
         frames: LinkFrames, given: dict, timeout: float
         ) -> Tuple[int, str, Optional[Solution]]:
    """The best-ranked exact solution that meets the request, with MoveIt's code and a message.

    NO_IK_SOLUTION: no exact solution (TIMED_OUT when the time ran out first), or every exact
    one collides while collisions are to be avoided; GOAL_CONSTRAINTS_VIOLATED: exact ones
    exist but none meets the constraints.
    """
    summary = (f'{len(result.solutions)} solutions, {result.elapsed * 1e3:.1f} ms')
    exact = [s for s in result.solutions if s.converged]
    if not exact:
        if result.timed_out:
            return E.TIMED_OUT, (f'timed out after {timeout * 1e3:.3f} ms with no exact '
                                 f'solution ({summary})'), None
        return E.NO_IK_SOLUTION, f'{result.message or "no exact solution"} ({summary})', None
    free = [s for s in exact if not (avoid_collisions and s.in_collision)]
    if not free:
        return E.NO_IK_SOLUTION, (f'every exact solution found ({len(exact)}) is in collision '
                                  f'({summary})'), None
    reason = None
    for s in free:
        why = rules.violation(s.q, joint_names, frames, given)
        if why is None:
            return E.SUCCESS, f'exact solution ({summary})', s
        reason = reason or why
    return E.GOAL_CONSTRAINTS_VIOLATED, (f'no exact solution found meets the constraints: '
                                         f'{reason} ({summary})'), None


def serve_moveit(node, group, qos) -> Optional[MoveItServices]:
    """Create ``/compute_ik`` and ``/compute_fk`` on ``node`` unless its parameters say not to.

    Without moveit_msgs in the environment the node serves without them (a warning says why).
    """
    if not node.params.moveit_services:
        return None
    if MISSING is not None:
        node.get_logger().warning(f'/compute_ik and /compute_fk are off: moveit_msgs cannot be '
                                  f'imported ({MISSING}); run scripts/setup.sh')
        return None
    return MoveItServices(node, group, qos)
