"""Conversions between ROS 2 messages and the sik_ros library (goals, seeds, obstacles, answers).

Part of :mod:`sik_ros.ros`, the only package that imports ROS message types. Functions here are
pure: they turn messages into arrays and :class:`~sik_ros.kinematics.collision.Obstacle` objects
(raising
:class:`~sik_ros.errors.SikError` subclasses on bad input, as the library does), and results
back into ``sik_interfaces`` messages and RViz markers. Units are SI: metres, radians, seconds.
"""

from array import array
import math
from typing import Dict, List, Optional, Sequence, Tuple

from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point, Pose
import numpy as np
from sensor_msgs.msg import JointState
from shape_msgs.msg import SolidPrimitive
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from sik_interfaces.msg import IKSolution, IKSolutionArray
from sik_interfaces.srv import SolveIK
from sik_ros.errors import (InvalidArgument, InvalidFrame, InvalidGoal, InvalidSeed,
                            ModelNotReady, SikError, SolverCrashed, SolverUnavailable)
from sik_ros.kinematics.chain import chain_forward
from sik_ros.kinematics.collision import BOX, CYLINDER, Obstacle, SPHERE
from sik_ros.solver import Solution

#: Name of every SolveIK error code, by value (for logs and tables).
ERROR_NAMES: Dict[int, str] = {
    SolveIK.Response.SUCCESS: 'SUCCESS',
    SolveIK.Response.NO_SOLUTION: 'NO_SOLUTION',
    SolveIK.Response.INVALID_GOAL: 'INVALID_GOAL',
    SolveIK.Response.INVALID_FRAME: 'INVALID_FRAME',
    SolveIK.Response.INVALID_SEED: 'INVALID_SEED',
    SolveIK.Response.TIMEOUT: 'TIMEOUT',
    SolveIK.Response.ROBOT_MISMATCH: 'ROBOT_MISMATCH',
    SolveIK.Response.JOINT_JUMP: 'JOINT_JUMP',
    SolveIK.Response.NO_ROBOT: 'NO_ROBOT',
    SolveIK.Response.MODEL_NOT_READY: 'MODEL_NOT_READY',
    SolveIK.Response.INTERNAL_ERROR: 'INTERNAL_ERROR',
}

_SHAPES = {SolidPrimitive.BOX: BOX, SolidPrimitive.SPHERE: SPHERE,
           SolidPrimitive.CYLINDER: CYLINDER}
_SHAPE_NAMES = {SolidPrimitive.BOX: 'box', SolidPrimitive.SPHERE: 'sphere',
                SolidPrimitive.CYLINDER: 'cylinder', SolidPrimitive.CONE: 'cone'}

# RViz colours (r, g, b, a): the best posture stands out, the others are translucent.
BEST_COLOR = (0.10, 0.80, 0.25, 1.0)
OTHER_COLOR = (0.25, 0.45, 0.95, 0.35)
COLLIDING_COLOR = (0.95, 0.45, 0.10, 0.35)
TARGET_COLOR = (0.90, 0.10, 0.10, 0.9)


def error_code_for(exc: SikError) -> int:
    """Return the SolveIK code of a library error.

    INVALID_SEED for seeds, INVALID_FRAME for frames, TIMEOUT when no solver was free in
    time, INTERNAL_ERROR for a solver process that died, MODEL_NOT_READY for raw answers
    before the arm's learned model, else INVALID_GOAL (bad input).
    """
    if isinstance(exc, ModelNotReady):
        return SolveIK.Response.MODEL_NOT_READY
    if isinstance(exc, InvalidSeed):
        return SolveIK.Response.INVALID_SEED
    if isinstance(exc, InvalidFrame):
        return SolveIK.Response.INVALID_FRAME
    if isinstance(exc, SolverUnavailable):
        return SolveIK.Response.TIMEOUT
    if isinstance(exc, SolverCrashed):
        return SolveIK.Response.INTERNAL_ERROR
    return SolveIK.Response.INVALID_GOAL


#: Most seconds a ``builtin_interfaces/Duration`` holds (its ``sec`` is an int32).
MAX_DURATION = float(2 ** 31 - 1)


def seconds_from_duration(duration: Duration, what: str = 'timeout') -> float:
    """Convert a ``builtin_interfaces/Duration`` to seconds [s].

    Raises:
        InvalidGoal: a negative duration, or nanoseconds of a second or more.
    """
    if duration.nanosec >= 1_000_000_000:
        raise InvalidGoal(f'{what}.nanosec must be below 1e9; got {duration.nanosec}')
    seconds = duration.sec + duration.nanosec * 1e-9
    if seconds < 0.0:
        raise InvalidGoal(f'{what} must not be negative; got {seconds:g} s')
    return seconds


def duration_from_seconds(seconds: float) -> Duration:
    """A ``builtin_interfaces/Duration`` of ``seconds`` >= 0, to the nearest nanosecond.

    Nanoseconds that round up to a whole second carry into ``sec``.

    Raises:
        InvalidGoal: not finite, negative, or beyond :data:`MAX_DURATION`.
    """
    if not 0.0 <= seconds <= MAX_DURATION:  # NaN too
        raise InvalidGoal(f'a duration of {seconds:g} s does not fit '
                          f'builtin_interfaces/Duration (0 to {MAX_DURATION:.0f} s)')
    sec = int(seconds)
    nanosec = int(round((seconds - sec) * 1e9))
    if nanosec >= 1_000_000_000:
        sec, nanosec = sec + 1, nanosec - 1_000_000_000
    return Duration(sec=sec, nanosec=nanosec)


def goal_from_pose(pose: Pose, use_orientation: bool
                   ) -> Tuple[np.ndarray, Optional[np.ndarray]]:
    """Target position (3,) [m] and quaternion (4,) x y z w, or None for a position goal.

    Values are passed on unchecked; :meth:`SelectiveIK.solve` rejects non-finite positions and
    zero or non-finite quaternions with :class:`~sik_ros.errors.InvalidGoal`.
    """
    p, o = pose.position, pose.orientation
    position = np.array([p.x, p.y, p.z], dtype=float)
    orientation = np.array([o.x, o.y, o.z, o.w], dtype=float) if use_orientation else None
    return position, orientation


def seed_from_joint_state(msg: JointState, joint_names: Sequence[str],
                          strict: bool = True) -> Optional[np.ndarray]:
    """Arm joint positions (n,) [rad] in ``joint_names`` order from a JointState, or None if empty.

    With names, values are matched by name (any order); without names they are taken in the
    arm's joint order (the count and the limits are checked by the solver).

    Args:
        msg: the seed; ``name`` may be empty.
        joint_names: the arm's joint names, in chain order.
        strict: reject names that are not arm joints (a seed in a request); when False they are
            ignored (a whole robot's ``joint_states``, fingers included).

    Raises:
        InvalidSeed: names and positions of different lengths, repeated or unknown names, or
            missing arm joints.
    """
    names, positions = list(msg.name), np.asarray(msg.position, dtype=float)
    if not names:
        return positions if len(positions) else None
    if len(names) != len(positions):
        raise InvalidSeed(f'seed has {len(names)} joint names but {len(positions)} positions')
    if len(set(names)) != len(names):
        raise InvalidSeed(f'seed names a joint twice: {names}')
    by_name = dict(zip(names, positions))
    unknown = [n for n in names if n not in joint_names]
    if strict and unknown:
        raise InvalidSeed(f'seed names unknown joints {unknown}; the arm joints are '
                          f'{list(joint_names)}')
    missing = [n for n in joint_names if n not in by_name]
    if missing:
        raise InvalidSeed(f'seed lacks the arm joints {missing}')
    return np.array([by_name[n] for n in joint_names], dtype=float)


def obstacles_from_msgs(primitives: Sequence[SolidPrimitive], poses: Sequence[Pose],
                        cap: Optional[int] = None) -> List[Obstacle]:
    """Obstacles in the base frame from SolidPrimitives and one Pose each, at most ``cap``.

    Raises:
        InvalidGoal: more than ``cap``, counts that differ, an unsupported shape (cone) or bad
            dimensions.
    """
    if cap is not None and len(primitives) > cap:
        raise InvalidGoal(f'{len(primitives)} obstacles; at most {cap} are accepted '
                          f'(parameter max_obstacles)')
    if len(primitives) != len(poses):
        raise InvalidGoal(f'{len(primitives)} obstacles but {len(poses)} obstacle_poses: give '
                          f'one pose per obstacle')
    out = []
    for k, (prim, pose) in enumerate(zip(primitives, poses)):
        if prim.type not in _SHAPES:
            name = _SHAPE_NAMES.get(prim.type, f'type {prim.type}')
            raise InvalidGoal(f'obstacle {k}: {name} is not supported (box, sphere, cylinder)')
        p, o = pose.position, pose.orientation
        try:
            out.append(Obstacle(_SHAPES[prim.type], tuple(float(d) for d in prim.dimensions),
                                (p.x, p.y, p.z), (o.x, o.y, o.z, o.w)))
        except InvalidArgument as exc:
            raise InvalidGoal(f'obstacle {k}: {exc}') from exc
    return out


def known_clearance(distance: float) -> float:
    """A clearance for a message [m]: NaN (a check the deadline cut short) becomes 0, touching."""
    return 0.0 if math.isnan(distance) else float(distance)


def _built_by_slots(cls) -> bool:
    """Whether ``cls`` keeps each field in a slot ``_<field>`` (rosidl's layout) and no other.

    Then :func:`_bare` may fill a message's slots at once; otherwise (another rosidl) the
    messages are built by their constructors.
    """
    fields = getattr(cls, '_fields_and_field_types', None)
    return fields is not None and set(cls.__slots__) == {f'_{f}' for f in fields} | {
        '_check_fields'}


#: Answers' messages are built slot by slot (:func:`_bare`): a constructor first builds a default
#: of every field (a ``JointState`` builds its ``Header``, ``Time`` and three arrays), which
#: the answer then replaces.
SLOTTED = _built_by_slots(IKSolution) and _built_by_slots(JointState)


#: The markers' points too (a few hundred per answer).
POINTS_BY_SLOTS = _built_by_slots(Point)


def _bare(cls):
    """A message of ``cls`` with no field set yet (the caller sets every one: :data:`SLOTTED`)."""
    msg = cls.__new__(cls)
    msg._check_fields = False
    return msg


def solution_to_msg(solution: Solution, joint_names: Sequence[str], header: Header
                    ) -> IKSolution:
    """One ranked library solution as an ``IKSolution`` (joint state stamped with ``header``).

    The arrays go into the ``array.array`` fields as bytes (one copy, no Python floats).
    ``header`` is shared, not copied: an answer's messages are only read (serialised).
    """
    return solution_msgs([solution], joint_names, header)[0]


def solution_msgs(solutions: Sequence[Solution], joint_names: Sequence[str], header: Header
                  ) -> List[IKSolution]:
    """Ranked library solutions as ``IKSolution`` messages, all stamped with ``header``.

    The messages share ``header``, the list of joint names and the empty velocity and effort
    arrays: an answer's messages are only read (serialised). Each array goes into its
    ``array.array`` field as bytes (one copy, no Python floats).
    """
    names = list(joint_names)
    out = []
    if not SLOTTED:
        for s in solutions:
            msg = IKSolution()
            state = msg.joint_state
            state.header, state.name = header, names
            state.position = array('d', np.asarray(s.q, dtype=float).tobytes())
            msg.posture_index = array('f', np.asarray(s.posture_index,
                                                      dtype=np.float32).tobytes())
            msg.position_error = float(s.position_error)
            msg.orientation_error = float(s.orientation_error)
            msg.min_obstacle_distance = known_clearance(s.min_obstacle_distance)
            msg.self_collision = bool(s.self_collision)
            msg.score = float(s.score)
            msg.tier = int(s.tier)
            msg.family = int(s.family)
            out.append(msg)
        return out
    empty = array('d')
    for s in solutions:
        state = _bare(JointState)
        state._header, state._name = header, names
        state._position = array('d', np.asarray(s.q, dtype=float).tobytes())
        state._velocity = state._effort = empty
        msg = _bare(IKSolution)
        msg._joint_state = state
        msg._posture_index = array('f', np.asarray(s.posture_index, dtype=np.float32).tobytes())
        msg._position_error = float(s.position_error)
        msg._orientation_error = float(s.orientation_error)
        msg._min_obstacle_distance = known_clearance(s.min_obstacle_distance)
        msg._self_collision = bool(s.self_collision)
        msg._score = float(s.score)
        msg._tier = int(s.tier)
        msg._family = int(s.family)
        out.append(msg)
    return out


def solution_array(header: Header, error_code: int, message: str,
                   solutions: Sequence[IKSolution]) -> IKSolutionArray:
    """Build the ``~/solutions`` message of one answer."""
    return IKSolutionArray(header=header, error_code=int(error_code), message=message,
                           solutions=list(solutions))


def _color(rgba: Tuple[float, float, float, float]) -> ColorRGBA:
    return ColorRGBA(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])


def _points(rows: np.ndarray) -> List[Point]:
    if not POINTS_BY_SLOTS:
        return [Point(x=float(x), y=float(y), z=float(z)) for x, y, z in rows]
    out = []
    for x, y, z in np.asarray(rows, dtype=float).tolist():
        point = _bare(Point)
        point._x, point._y, point._z = x, y, z
        out.append(point)
    return out


def posture_markers(chain, solutions: Sequence[Solution], header: Header,
                    target_position: Optional[np.ndarray] = None,
                    target_orientation: Optional[np.ndarray] = None) -> MarkerArray:
    """Draw ranked postures for RViz: a DELETEALL, the target, then one namespace per rank.

    Each rank ``rank_NN`` holds a LINE_STRIP from the base through every joint origin to the tip
    (id 0) and a SPHERE_LIST at the joint origins (id 1). The best posture is opaque green,
    the others translucent (blue, or orange when they touch an obstacle).

    Args:
        chain: the robot's :class:`~sik_ros.kinematics.chain.SerialChain`.
        solutions: ranked solutions, best first.
        header: frame (the base frame) and stamp of every marker.
        target_position: the goal position [m] (no target marker if None).
        target_orientation: the goal quaternion x y z w (adds an arrow along the tool z axis).
    """
    markers = [Marker(header=header, action=Marker.DELETEALL)]
    if target_position is not None and np.all(np.isfinite(target_position)):
        target = Marker(header=header, ns='target', id=0, type=Marker.SPHERE,
                        action=Marker.ADD, color=_color(TARGET_COLOR))
        target.pose.position = _points(np.asarray(target_position)[None])[0]
        target.scale.x = target.scale.y = target.scale.z = 0.03
        markers.append(target)
        if target_orientation is not None and np.all(np.isfinite(target_orientation)) \
                and np.linalg.norm(target_orientation) > 1e-9:
            quat = np.asarray(target_orientation, dtype=float)
            x, y, z, w = quat / np.linalg.norm(quat)
            axis_z = 2 * np.array([x * z + w * y, y * z - w * x, 0.5 - x * x - y * y])
            axis_z /= np.linalg.norm(axis_z)
            arrow = Marker(header=header, ns='target', id=1, type=Marker.ARROW,
                           action=Marker.ADD, color=_color(TARGET_COLOR))
            arrow.points = _points(np.stack([target_position - 0.1 * axis_z, target_position]))
            arrow.scale.x, arrow.scale.y, arrow.scale.z = 0.01, 0.02, 0.02
            markers.append(arrow)
    if solutions:
        q = np.array([s.q for s in solutions], dtype=float)
        tip, _, origins, _ = chain_forward(chain, q, frames=True)
        base = np.zeros((len(q), 1, 3))
        strips = np.concatenate([base, origins, tip[:, None]], axis=1)
        for rank, (sol, strip) in enumerate(zip(solutions, strips)):
            if rank == 0:
                rgba, width = BEST_COLOR, 0.02
            else:
                rgba = COLLIDING_COLOR if sol.in_collision else OTHER_COLOR
                width = 0.01
            ns = f'rank_{rank:02d}'
            line = Marker(header=header, ns=ns, id=0, type=Marker.LINE_STRIP, action=Marker.ADD,
                          color=_color(rgba), points=_points(strip))
            line.pose.orientation.w = 1.0
            line.scale.x = width
            joints = Marker(header=header, ns=ns, id=1, type=Marker.SPHERE_LIST,
                            action=Marker.ADD, color=_color(rgba),
                            points=_points(strip[1:-1]))
            joints.pose.orientation.w = 1.0
            joints.scale.x = joints.scale.y = joints.scale.z = 2.5 * width
            markers += [line, joints]
    return MarkerArray(markers=markers)


def solution_count(asked: int, default: int, cap: int) -> Tuple[int, str]:
    """Solutions to return for a request's ``max_solutions`` (0: the default), and a note."""
    if asked == 0:
        return default, ''
    if asked > cap:
        return cap, f'max_solutions {asked} clamped to the cap max_solutions_cap={cap}'
    return asked, ''


def result_code(result, obstacles: bool, timeout: float) -> Tuple[int, str]:
    """The SolveIK code and message of a library result.

    ``TIMEOUT`` when the deadline stopped the collision checks before a collision-free
    solution was confirmed, or came before any solution within tolerance.
    """
    R = SolveIK.Response
    exact = sum(s.converged for s in result.solutions)
    summary = (f'{len(result.solutions)} solutions, {exact} within tolerance, '
               f'{result.num_families} posture families')
    if obstacles:
        summary += f', {sum(not s.in_collision for s in result.solutions)} collision-free'
    summary += f', {result.goal} goal, {result.elapsed * 1e3:.1f} ms'
    unchecked = result.timed_out and obstacles and not any(
        s.converged and not s.in_collision for s in result.solutions)
    if unchecked:
        return R.TIMEOUT, (f'timed out after {timeout * 1e3:.0f} ms before a collision-free '
                           f'solution was confirmed ({summary})')
    if result.success:
        return R.SUCCESS, summary
    if result.timed_out:
        return R.TIMEOUT, (f'timed out after {timeout * 1e3:.0f} ms with no solution within '
                           f'tolerance ({summary})')
    return R.NO_SOLUTION, f'{result.message or "no solution"} ({summary})'
