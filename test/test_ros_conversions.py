"""Message <-> library conversions of the ROS layer (sik_ros.ros.conversions), without a node."""

import math

from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Pose
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState
from shape_msgs.msg import SolidPrimitive
from std_msgs.msg import Header
from visualization_msgs.msg import Marker

from sik_interfaces.msg import IKSolution, IKSolutionArray
from sik_interfaces.srv import SolveIK
from sik_ros.errors import (InvalidArgument, InvalidGoal, InvalidSeed, JointLimitViolation,
                            ModelNotReady)
from sik_ros.ros import conversions as conv
from sik_ros.solver import Solution

R = SolveIK.Response
NAMES = [f'panda_joint{i}' for i in range(1, 8)]


def pose(x=0.0, y=0.0, z=0.0, q=(0.0, 0.0, 0.0, 1.0)):
    p = Pose()
    p.position.x, p.position.y, p.position.z = x, y, z
    p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w = q
    return p


def solution(q, clearance=math.inf, self_collision=False, score=0.5):
    return Solution(np.asarray(q, dtype=float), 2e-5, 1e-4, np.array([0.25, -0.5], np.float32),
                    score, clearance, self_collision, True)


# -- goals, seeds, obstacles, durations -----------------------------------------------------------

def test_goal_orientation_only_when_asked():
    """A Pose gives the position, and the quaternion x y z w only with use_orientation."""
    msg = pose(0.1, 0.2, 0.3, (0.0, 1.0, 0.0, 0.0))
    position, orientation = conv.goal_from_pose(msg, False)
    assert position.tolist() == [0.1, 0.2, 0.3] and orientation is None
    _, orientation = conv.goal_from_pose(msg, True)
    assert orientation.tolist() == [0.0, 1.0, 0.0, 0.0]


def test_seed_matched_by_name_in_any_order():
    """Named seed values are reordered into the arm's joint order."""
    msg = JointState(name=list(reversed(NAMES)), position=[7.0, 6, 5, 4, 3, 2, 1])
    assert conv.seed_from_joint_state(msg, NAMES).tolist() == [1, 2, 3, 4, 5, 6, 7]


def test_seed_without_names_is_in_arm_order_and_empty_is_none():
    """Without names the positions are taken as they are; an empty JointState is no seed."""
    msg = JointState(position=[0.5, 0.25])
    assert conv.seed_from_joint_state(msg, NAMES).tolist() == [0.5, 0.25]
    assert conv.seed_from_joint_state(JointState(), NAMES) is None


@pytest.mark.parametrize('names, positions, why', [
    (NAMES, [0.0] * 6, 'positions'),
    (NAMES[:6] + [NAMES[0]], [0.0] * 7, 'twice'),
    (NAMES + ['panda_finger_joint1'], [0.0] * 8, 'unknown'),
    (NAMES[:6], [0.0] * 6, 'lacks'),
], ids=['count mismatch', 'repeated name', 'unknown joint', 'missing joint'])
def test_bad_named_seed_is_invalid_seed(names, positions, why):
    """Names that do not match the positions or the arm joints raise InvalidSeed, saying why."""
    with pytest.raises(InvalidSeed, match=why):
        conv.seed_from_joint_state(JointState(name=names, position=positions), NAMES)


def test_joint_states_may_name_other_joints():
    """Non-strict (a robot's joint_states): joints other than the arm's are ignored."""
    msg = JointState(name=['panda_finger_joint1'] + NAMES, position=[0.04] + list(range(7)))
    assert conv.seed_from_joint_state(msg, NAMES, strict=False).tolist() == list(range(7))


def test_obstacles_from_primitives_and_poses():
    """Box, sphere and cylinder primitives with poses become Obstacles with the same numbers."""
    prims = [SolidPrimitive(type=SolidPrimitive.BOX, dimensions=[0.1, 0.2, 0.3]),
             SolidPrimitive(type=SolidPrimitive.SPHERE, dimensions=[0.05]),
             SolidPrimitive(type=SolidPrimitive.CYLINDER, dimensions=[0.4, 0.02])]
    poses = [pose(0.5, 0, 0.2), pose(0, 0.5, 0.3, (0, 0, 0.7071, 0.7071)), pose(z=1.0)]
    obs = conv.obstacles_from_msgs(prims, poses)
    assert [o.shape for o in obs] == ['box', 'sphere', 'cylinder']
    assert obs[0].dimensions == (0.1, 0.2, 0.3) and obs[0].position == (0.5, 0.0, 0.2)
    assert obs[1].quaternion == (0.0, 0.0, 0.7071, 0.7071)
    assert obs[2].dimensions == (0.4, 0.02)


@pytest.mark.parametrize('prims, poses, why', [
    ([SolidPrimitive(type=SolidPrimitive.BOX, dimensions=[0.1, 0.1, 0.1])], [], 'one pose'),
    ([SolidPrimitive(type=SolidPrimitive.CONE, dimensions=[0.1, 0.1])], [Pose()], 'cone'),
    ([SolidPrimitive(type=SolidPrimitive.BOX, dimensions=[0.1, 0.1])], [Pose()], 'obstacle 0'),
    ([SolidPrimitive(type=SolidPrimitive.SPHERE, dimensions=[-1.0])], [Pose()], 'positive'),
], ids=['missing pose', 'cone', 'box with 2 sides', 'negative radius'])
def test_bad_obstacles_are_invalid_goal(prims, poses, why):
    """Unpaired, unsupported or badly sized obstacles raise InvalidGoal with a reason."""
    with pytest.raises(InvalidGoal, match=why):
        conv.obstacles_from_msgs(prims, poses)


def test_duration_in_seconds():
    """A Duration converts to seconds; a negative one is refused."""
    assert conv.seconds_from_duration(Duration(sec=1, nanosec=500_000_000)) == 1.5
    assert conv.seconds_from_duration(Duration()) == 0.0
    with pytest.raises(InvalidArgument):
        conv.seconds_from_duration(Duration(sec=-1))


def test_error_codes_of_library_errors():
    """Seed errors map to INVALID_SEED, raw answers with no model to MODEL_NOT_READY; else GOAL."""
    assert conv.error_code_for(JointLimitViolation('j', 4.0, -1.0, 1.0)) == R.INVALID_SEED
    assert conv.error_code_for(ModelNotReady('x')) == R.MODEL_NOT_READY
    assert conv.error_code_for(InvalidSeed('x')) == R.INVALID_SEED
    assert conv.error_code_for(InvalidGoal('x')) == R.INVALID_GOAL
    assert conv.error_code_for(InvalidArgument('x')) == R.INVALID_GOAL
    assert set(conv.ERROR_NAMES.values()) == {
        'SUCCESS', 'NO_SOLUTION', 'INVALID_GOAL', 'INVALID_FRAME', 'INVALID_SEED', 'TIMEOUT',
        'ROBOT_MISMATCH', 'JOINT_JUMP', 'NO_ROBOT', 'MODEL_NOT_READY', 'INTERNAL_ERROR'}


# -- answers and markers --------------------------------------------------------------------------

def test_solution_message_fields():
    """An IKSolution carries names, positions, posture index, errors, clearance and score."""
    header = Header(frame_id='panda_link0')
    msg = conv.solution_to_msg(solution(np.arange(7) * 0.1), NAMES, header)
    assert list(msg.joint_state.name) == NAMES
    assert msg.joint_state.header.frame_id == 'panda_link0'
    assert np.allclose(msg.joint_state.position, np.arange(7) * 0.1)
    assert list(msg.posture_index) == [0.25, -0.5]
    assert (msg.position_error, msg.orientation_error, msg.score) == (2e-5, 1e-4, 0.5)
    assert math.isinf(msg.min_obstacle_distance)
    assert msg.family == IKSolution.NO_FAMILY  # a Solution made without a family
    array = conv.solution_array(header, R.SUCCESS, 'ok', [msg])
    assert deserialize_message(serialize_message(array), IKSolutionArray) == array


def test_solution_family_round_trips():
    """A solution's family goes into IKSolution.family and survives serialization."""
    sol = solution(np.zeros(7))
    sol.family = 2
    msg = conv.solution_to_msg(sol, NAMES, Header(frame_id='panda_link0'))
    assert msg.family == 2
    array = conv.solution_array(Header(), R.SUCCESS, '', [msg])
    assert deserialize_message(serialize_message(array), IKSolutionArray).solutions[0].family == 2


def test_markers_show_ranked_postures(panda):
    """DELETEALL, the target, and per rank a line strip base -> joints -> FK tip, best first."""
    rng = np.random.default_rng(0)
    qs = rng.uniform(panda.lower, panda.upper, (3, 7))
    sols = [solution(qs[0]), solution(qs[1], clearance=-0.01), solution(qs[2])]
    header = Header(frame_id='panda_link0')
    target = np.array([0.4, 0.1, 0.5])
    markers = conv.posture_markers(panda.chain, sols, header, target,
                                   np.array([1.0, 0.0, 0.0, 0.0])).markers
    assert markers[0].action == Marker.DELETEALL
    sphere, arrow = markers[1], markers[2]
    assert (sphere.ns, sphere.type) == ('target', Marker.SPHERE)
    assert [sphere.pose.position.x, sphere.pose.position.y, sphere.pose.position.z] == \
        target.tolist()
    assert arrow.type == Marker.ARROW
    tail, head = arrow.points  # gripper pointing down: the arrow points down onto the target
    assert head.z == pytest.approx(0.5) and tail.z == pytest.approx(0.6)
    strips = [m for m in markers if m.type == Marker.LINE_STRIP]
    joints = [m for m in markers if m.type == Marker.SPHERE_LIST]
    assert [m.ns for m in strips] == ['rank_00', 'rank_01', 'rank_02'] == [m.ns for m in joints]
    for strip, q in zip(strips, qs):
        tip, _ = panda.fk(q)
        points = np.array([[p.x, p.y, p.z] for p in strip.points])
        assert len(points) == 9 and np.allclose(points[0], 0) and np.allclose(points[-1], tip)
    best, colliding, other = strips
    assert best.color.a == 1.0 and best.scale.x > other.scale.x
    assert (colliding.color.r, colliding.color.g) != (other.color.r, other.color.g)
    assert all(m.header.frame_id == 'panda_link0' for m in markers)


def test_markers_without_solutions_or_valid_target():
    """No solutions and a non-finite target: only the DELETEALL marker."""
    markers = conv.posture_markers(None, [], Header(), np.array([np.nan, 0, 0])).markers
    assert [m.action for m in markers] == [Marker.DELETEALL]


@pytest.mark.parametrize('seconds, expected', [
    (1.9999999999, (2, 0)), (0.0, (0, 0)), (2.5, (2, 500_000_000)), (1e-9, (0, 1)),
    (0.9999999996, (1, 0)), (2.0 ** 31 - 1, (2 ** 31 - 1, 0))])
def test_durations_carry_nanoseconds_that_round_to_a_second(seconds, expected):
    """A duration whose nanoseconds round up to 1e9 carries a second (1.9999999999 s -> 2 s)."""
    d = conv.duration_from_seconds(seconds)
    assert (d.sec, d.nanosec) == expected


@pytest.mark.parametrize('seconds', [-1e-9, math.nan, math.inf, 2.0 ** 31, 1e300])
def test_durations_that_do_not_fit_are_invalid_goals(seconds):
    """Negative, non-finite and too long durations are refused, not wrapped or raised raw."""
    with pytest.raises(InvalidGoal, match='Duration'):
        conv.duration_from_seconds(seconds)


def test_trajectory_times_strictly_increase_past_two_thousand_points():
    """2,500 minimal segments: every time_from_start later than the one before, seconds kept."""
    from sik_ros.ros.trajectories import segment_times
    q = np.zeros((2500, 7))
    times = segment_times(q, np.full(7, 2.0), 1.0)
    durations = [conv.duration_from_seconds(t) for t in times]
    ns = [d.sec * 1_000_000_000 + d.nanosec for d in durations]
    assert all(b > a for a, b in zip(ns, ns[1:]))
    assert durations[-1].sec == 2 and all(d.nanosec < 1_000_000_000 for d in durations)


@pytest.mark.parametrize('scaling', [1e-300, 1e-12])
def test_a_tiny_velocity_scaling_that_overflows_a_duration_is_an_invalid_goal(scaling):
    """A path that would last beyond what Duration holds is refused by name."""
    from sik_ros.ros.trajectories import segment_times
    q = np.linspace(0.0, 1.0, 5)[:, None] * np.ones(7)
    with pytest.raises(InvalidGoal, match='velocity_scaling'):
        segment_times(q, np.full(7, 2.0), scaling)


def test_negative_or_malformed_timeouts_are_invalid_goals():
    """A negative timeout, or nanoseconds of a second or more, is INVALID_GOAL."""
    for sec, nanosec in ((-1, 0), (0, 1_000_000_000)):
        with pytest.raises(InvalidGoal):
            conv.seconds_from_duration(Duration(sec=sec, nanosec=nanosec))
    assert conv.error_code_for(InvalidGoal('x')) == R.INVALID_GOAL


def test_the_answer_message_counts_the_posture_families():
    """A SolveIK answer's message says how many posture families the solve found."""
    from sik_ros.solver.results import IKResult
    code, text = conv.result_code(IKResult(success=False, num_families=3), False, 0.05)
    assert '3 posture families' in text and code == SolveIK.Response.NO_SOLUTION
