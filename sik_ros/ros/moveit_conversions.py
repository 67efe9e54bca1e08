"""Conversions between ``moveit_msgs`` and the library for ``/compute_ik`` and ``/compute_fk``.

Pure functions, as :mod:`~sik_ros.ros.conversions` for ``sik_interfaces``: a request's robot
state into the arm's joint values (by name, any order) and the other joints it gave, a stamped
pose into a tip goal in the base frame (through frames fixed to the base and links fixed to the
tip), ``moveit_msgs/Constraints`` into :class:`~sik_ros.solver.goal_constraints.GoalConstraints`,
and answers back into ``RobotState`` and ``PoseStamped``. Bad input raises a
:class:`MoveItRefusal` carrying MoveIt's code, or a :class:`~sik_ros.errors.SikError` of the
library (:func:`moveit_code` gives its code).
"""

from array import array
from dataclasses import dataclass
import math
from typing import Dict, List, Optional, Sequence, Tuple

from geometry_msgs.msg import Pose
from moveit_msgs.msg import Constraints, MoveItErrorCodes, RobotState
import numpy as np
from sensor_msgs.msg import JointState
from shape_msgs.msg import SolidPrimitive
from std_msgs.msg import Header

from sik_interfaces.srv import SolveIK
from sik_ros.errors import InvalidGoal, SikError
from sik_ros.kinematics.link_frames import LinkFrames, Transform
from sik_ros.kinematics.rotations import matrix_quaternion, quaternion_matrix
from sik_ros.solver.goal_constraints import (GoalConstraints, InvalidConstraint,
                                             OrientationRule, PositionRule, Region)

E = MoveItErrorCodes
R = SolveIK.Response
#: Most joints a request's robot state may name (a whole robot has far fewer).
MAX_STATE_JOINTS = 1024
#: MoveIt's code for each ``SolveIK`` code the node's guard may give.
MOVEIT_CODES = {R.SUCCESS: E.SUCCESS, R.NO_SOLUTION: E.NO_IK_SOLUTION,
                R.INVALID_GOAL: E.INVALID_GOAL_CONSTRAINTS, R.INVALID_FRAME:
                E.FRAME_TRANSFORM_FAILURE, R.INVALID_SEED: E.INVALID_ROBOT_STATE,
                R.TIMEOUT: E.TIMED_OUT, R.ROBOT_MISMATCH: E.FAILURE,
                R.JOINT_JUMP: E.FAILURE, R.INTERNAL_ERROR: E.FAILURE}
#: The ``SolveIK`` code counted in the node's statistics for each MoveIt code.
STATISTICS_CODES = {E.SUCCESS: R.SUCCESS, E.NO_IK_SOLUTION: R.NO_SOLUTION,
                    E.GOAL_CONSTRAINTS_VIOLATED: R.NO_SOLUTION, E.TIMED_OUT: R.TIMEOUT,
                    E.INVALID_ROBOT_STATE: R.INVALID_SEED,
                    E.FRAME_TRANSFORM_FAILURE: R.INVALID_FRAME, E.FAILURE: R.INTERNAL_ERROR}
_SHAPES = {SolidPrimitive.BOX: 'box', SolidPrimitive.SPHERE: 'sphere',
           SolidPrimitive.CYLINDER: 'cylinder'}


class MoveItRefusal(SikError):
    """A request answered with a MoveIt error code and a message."""

    def __init__(self, code: int, message: str):
        self.code = int(code)
        super().__init__(message)


def moveit_code(solve_ik_code: int) -> int:
    """The MoveIt code of a ``SolveIK`` code (``FAILURE`` for any other)."""
    return MOVEIT_CODES.get(int(solve_ik_code), E.FAILURE)


@dataclass(frozen=True)
class GivenState:
    """The joints a request's robot state named, as given.

    Attributes:
        names: joint names, in the request's order.
        positions: their values (as given) [rad or m].
        is_diff: the state only changes the node's current one (``RobotState.is_diff``).
    """

    names: List[str]
    positions: np.ndarray
    is_diff: bool

    def values(self) -> Dict[str, float]:
        """Values by name."""
        return dict(zip(self.names, self.positions.tolist()))


def given_state(state: RobotState) -> GivenState:
    """The joints of a request's robot state, checked for shape.

    Raises:
        MoveItRefusal: INVALID_ROBOT_STATE for more than :data:`MAX_STATE_JOINTS` joints,
            names and positions of different lengths, positions without names, or a name given
            twice.
    """
    js = state.joint_state
    count = max(len(js.name), len(js.position))
    if count > MAX_STATE_JOINTS:
        raise MoveItRefusal(E.INVALID_ROBOT_STATE, f'robot_state names {count} joints; at '
                            f'most {MAX_STATE_JOINTS} are accepted')
    names, positions = list(js.name), np.asarray(js.position, dtype=float)
    if len(names) != len(positions):
        raise MoveItRefusal(E.INVALID_ROBOT_STATE, f'robot_state.joint_state has {len(names)} '
                            f'names but {len(positions)} positions')
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise MoveItRefusal(E.INVALID_ROBOT_STATE, f'robot_state names joints twice: {twice}')
    return GivenState(names, positions, bool(state.is_diff))


def arm_values(given: GivenState, joint_names: Sequence[str], current: Optional[JointState],
               what: str = 'robot_state') -> Optional[np.ndarray]:
    """The arm's joint values (n,) from a request's state, or None when it names none.

    A full state (``is_diff`` false) must give every arm joint it gives any joint for; an empty
    one stands for the node's current state (``current``, the latest ``joint_states``). A diff
    takes the arm joints it does not name from ``current``.

    Raises:
        MoveItRefusal: INVALID_ROBOT_STATE for an arm joint that is missing or not finite.
    """
    values = given.values()
    base = {} if current is None else dict(zip(current.name, current.position))
    if not values and not given.is_diff:
        values = base if len(base) else {}
    elif given.is_diff:
        values = dict(base, **values)
    if not any(n in values for n in joint_names):
        return None
    missing = [n for n in joint_names if n not in values]
    if missing:
        source = ' or the latest joint_states' if given.is_diff else ' (is_diff is false)'
        raise MoveItRefusal(E.INVALID_ROBOT_STATE, f'{what} lacks the arm joints {missing}'
                            f'{source}')
    q = np.array([values[n] for n in joint_names], dtype=float)
    if not np.all(np.isfinite(q)):
        raise MoveItRefusal(E.INVALID_ROBOT_STATE, f'{what} arm joints are not finite: '
                            f'{q.tolist()}')
    return q


def transform_of(pose: Pose, what: str) -> Transform:
    """A pose message as a :class:`Transform` (its quaternion normalised).

    Raises:
        InvalidGoal: a position or quaternion that is not finite, or a zero quaternion.
    """
    p, o = pose.position, pose.orientation
    position = np.array([p.x, p.y, p.z], dtype=float)
    quat = np.array([o.x, o.y, o.z, o.w], dtype=float)
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(quat))):
        raise InvalidGoal(f'{what} is not finite: position {position.tolist()}, orientation '
                          f'{quat.tolist()}')
    if np.linalg.norm(quat) < 1e-9:
        raise InvalidGoal(f'{what} has a zero quaternion')
    return Transform(quaternion_matrix(quat), position)


def frame_in_base(frames: LinkFrames, frame_id: str, what: str) -> Transform:
    """Where a frame is in the base frame: ``''``, the base, or a frame fixed to it.

    Raises:
        MoveItRefusal: FRAME_TRANSFORM_FAILURE for any other frame.
    """
    placed = frames.in_base(frame_id)
    if placed is None:
        raise MoveItRefusal(E.FRAME_TRANSFORM_FAILURE, f'{what} frame_id {frame_id!r} is not '
                            f'the base frame or a frame fixed to it ({frames.base_fixed})')
    return placed


def tip_goal(frames: LinkFrames, pose: Pose, frame_id: str, link: str
             ) -> Tuple[np.ndarray, np.ndarray]:
    """The tip's goal in the base frame for ``link`` at ``pose`` in ``frame_id``.

    Returns:
        position (3,) [m] and quaternion (4,) x y z w; as given when both frames are the base's
        and the tip's own.

    Raises:
        MoveItRefusal: FRAME_TRANSFORM_FAILURE (frame), INVALID_LINK_NAME (a link not fixed to
            the tip).
        InvalidGoal: a pose that is not one.
    """
    offset = frames.from_tip(link)
    if offset is None:
        raise MoveItRefusal(E.INVALID_LINK_NAME, f'ik_link_name {link!r} is not the tip or a '
                            f'link fixed to it ({frames.tip_fixed})')
    frame = frame_in_base(frames, frame_id, 'pose_stamped.header')
    goal = transform_of(pose, 'pose_stamped.pose')
    if not (frame.is_identity and offset.is_identity):
        goal = frame @ goal @ offset.inverse()
        return goal.translation, matrix_quaternion(goal.rotation)
    o = pose.orientation
    return goal.translation, np.array([o.x, o.y, o.z, o.w], dtype=float)


def _number(value: float, what: str) -> float:
    if not math.isfinite(value):
        raise InvalidConstraint(f'{what} is not finite: {value}')
    return float(value)


def goal_constraints(msg: Constraints, joint_names: Sequence[str], frames: LinkFrames,
                     given: GivenState) -> GoalConstraints:
    """``moveit_msgs/Constraints`` as :class:`GoalConstraints`.

    Raises:
        InvalidConstraint: a joint neither in the arm nor in the request's state, a link the
            arm does not place, a frame not fixed to the base, non-finite numbers, meshes, cones
            or visibility constraints.
        MoveItRefusal: FRAME_TRANSFORM_FAILURE for a constraint's frame.
    """
    n = len(joint_names)
    lower, upper = np.full(n, -np.inf), np.full(n, np.inf)
    others: Dict[str, Tuple[float, float]] = {}
    index = {name: i for i, name in enumerate(joint_names)}
    for k, c in enumerate(msg.joint_constraints):
        what = f'joint_constraints[{k}]'
        lo = _number(c.position, what) - _number(c.tolerance_below, what)
        hi = c.position + _number(c.tolerance_above, what)
        if c.joint_name in index:
            i = index[c.joint_name]
            lower[i], upper[i] = max(lower[i], lo), min(upper[i], hi)
        elif c.joint_name in given.names:
            old = others.get(c.joint_name, (-np.inf, np.inf))
            others[c.joint_name] = (max(old[0], lo), min(old[1], hi))
        else:
            raise InvalidConstraint(f'{what}: joint {c.joint_name!r} is neither an arm joint '
                                    f'nor in robot_state')
    positions = tuple(_position_rule(c, k, frames) for k, c in
                      enumerate(msg.position_constraints))
    orientations = tuple(_orientation_rule(c, k, frames) for k, c in
                         enumerate(msg.orientation_constraints))
    if len(msg.visibility_constraints):
        raise InvalidConstraint('visibility constraints are not supported')
    return GoalConstraints(lower, upper, others, positions, orientations)


def _placeable(frames: LinkFrames, link: str, what: str) -> str:
    if not frames.placeable(link):
        raise InvalidConstraint(f'{what}: link {link!r} is not placed by the arm\'s joints')
    return link


def _position_rule(c, k: int, frames: LinkFrames) -> PositionRule:
    what = f'position_constraints[{k}]'
    link = _placeable(frames, c.link_name, what)
    frame = frame_in_base(frames, c.header.frame_id, f'{what}.header')
    volume = c.constraint_region
    if len(volume.meshes):
        raise InvalidConstraint(f'{what}: mesh regions are not supported (boxes, spheres, '
                                f'cylinders)')
    if not len(volume.primitives) or len(volume.primitives) != len(volume.primitive_poses):
        raise InvalidConstraint(f'{what}: give at least one primitive and one pose for each '
                                f'({len(volume.primitives)} and '
                                f'{len(volume.primitive_poses)})')
    regions = []
    for prim, pose in zip(volume.primitives, volume.primitive_poses):
        kind = _SHAPES.get(prim.type, f'type {prim.type}')
        placed = frame @ transform_of(pose, f'{what} primitive pose')
        regions.append(Region(kind, tuple(float(d) for d in prim.dimensions), placed))
    v = c.target_point_offset
    offset = np.array([_number(x, what) for x in (v.x, v.y, v.z)])
    return PositionRule(link, offset, tuple(regions))


def _orientation_rule(c, k: int, frames: LinkFrames) -> OrientationRule:
    what = f'orientation_constraints[{k}]'
    link = _placeable(frames, c.link_name, what)
    frame = frame_in_base(frames, c.header.frame_id, f'{what}.header')
    if c.parameterization not in (c.XYZ_EULER_ANGLES, c.ROTATION_VECTOR):
        raise InvalidConstraint(f'{what}: unknown parameterization {c.parameterization}')
    pose = Pose()
    pose.orientation = c.orientation
    target = frame.rotation @ transform_of(pose, f'{what}.orientation').rotation
    tol = np.array([_number(t, what) for t in (c.absolute_x_axis_tolerance,
                                               c.absolute_y_axis_tolerance,
                                               c.absolute_z_axis_tolerance)])
    return OrientationRule(link, target, tol, c.parameterization == c.ROTATION_VECTOR)


def solution_state(given: GivenState, joint_names: Sequence[str], q: np.ndarray,
                   header: Header, source: RobotState) -> RobotState:
    """The answer: the request's joints as given, the arm's set to ``q`` (n,) [rad].

    Arm joints the request did not name follow its joints; its multi-DOF joints are returned
    as given, its attached objects not (as MoveIt answers).
    """
    values = dict(zip(joint_names, np.asarray(q, dtype=float).tolist()))
    names = list(given.names) + [n for n in joint_names if n not in set(given.names)]
    positions = [values.get(n, v) for n, v in zip(given.names, given.positions.tolist())]
    positions += [values[n] for n in names[len(given.names):]]
    state = RobotState()
    state.joint_state.header = header
    state.joint_state.name = names
    state.joint_state.position = array('d', positions)
    state.multi_dof_joint_state = source.multi_dof_joint_state
    return state


def pose_of(transform: Transform) -> Pose:
    """A :class:`Transform` as a pose message."""
    pose = Pose()
    t = transform.translation
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in t)
    x, y, z, w = matrix_quaternion(transform.rotation)
    pose.orientation.x, pose.orientation.y = float(x), float(y)
    pose.orientation.z, pose.orientation.w = float(z), float(w)
    return pose
