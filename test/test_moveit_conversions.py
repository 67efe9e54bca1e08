"""The parts of /compute_ik and /compute_fk that need no node: links, states, goals, rules."""

from geometry_msgs.msg import Pose
from moveit_msgs.msg import (Constraints, JointConstraint, MoveItErrorCodes as E,
                             PositionConstraint, RobotState, VisibilityConstraint)
import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import JointState
from shape_msgs.msg import Mesh, SolidPrimitive
from std_msgs.msg import Header

from sik_ros.errors import InvalidGoal
from sik_ros.kinematics.link_frames import LinkFrames, Transform
from sik_ros.ros import moveit_conversions as mc
from sik_ros.solver.goal_constraints import (GoalConstraints, InvalidConstraint,
                                             JointRangeCost, OrientationRule, Region)


@pytest.fixture(scope='module')
def ur5_frames(ur5):
    """The UR5's links (``world`` and ``base`` fixed to base_link, tool0 to wrist_3_link)."""
    return LinkFrames(ur5)


def pose_msg(t: Transform) -> Pose:
    """A Transform as a Pose."""
    return mc.pose_of(t)


def robot_state(names, positions, is_diff=False):
    """A RobotState of joint names and values."""
    return RobotState(joint_state=JointState(name=list(names), position=list(positions)),
                      is_diff=is_diff)


def test_link_classes(ur5, ur5_frames):
    """Base-fixed, tip-fixed and moving links of the UR5; the tip placed as the chain's FK."""
    f = ur5_frames
    assert {'world', 'base_link'} <= set(f.base_fixed)
    assert {'tool0', 'wrist_3_link'} <= set(f.tip_fixed) and 'shoulder_link' in f.moving
    assert f.in_base('') is not None and f.in_base('').is_identity
    assert f.from_tip('').is_identity and f.in_base('shoulder_link') is None
    rng = np.random.default_rng(0)
    qs = rng.uniform(ur5.lower, ur5.upper, size=(5, ur5.dof))
    for q in qs:
        tip, = f.poses(q, [ur5.tip_frame])
        p, quat = ur5.fk(q)
        assert np.allclose(tip.translation, p, atol=1e-12)
        assert np.allclose(tip.rotation, Rotation.from_quat(quat).as_matrix(), atol=1e-12)
    assert len(qs) == 5


def test_tip_goal_through_fixed_frames(ur5, ur5_frames):
    """A goal for wrist_3_link given in ``world`` becomes the tool0 pose of the same posture."""
    f = ur5_frames
    q = np.array([0.3, -1.1, 1.2, -0.4, 0.9, 0.2])
    world = f.in_base('world')
    wrist, = f.poses(q, ['wrist_3_link'])
    position, quat = mc.tip_goal(f, pose_msg(world.inverse() @ wrist), 'world', 'wrist_3_link')
    p, expected = ur5.fk(q)
    assert np.allclose(position, p, atol=1e-9)
    assert abs(abs(float(np.dot(quat, expected))) - 1.0) < 1e-9
    with pytest.raises(mc.MoveItRefusal) as refused:
        mc.tip_goal(f, pose_msg(wrist), 'map', '')
    assert refused.value.code == E.FRAME_TRANSFORM_FAILURE
    with pytest.raises(mc.MoveItRefusal) as refused:
        mc.tip_goal(f, pose_msg(wrist), '', 'forearm_link')
    assert refused.value.code == E.INVALID_LINK_NAME
    zero = pose_msg(wrist)
    zero.orientation.w = zero.orientation.x = zero.orientation.y = zero.orientation.z = 0.0
    with pytest.raises(InvalidGoal):
        mc.tip_goal(f, zero, '', '')


def test_arm_values_by_name_diff_and_current():
    """Arm joints by name in any order; a diff fills from joint_states; a full state must not."""
    arm = ['a', 'b', 'c']
    given = mc.given_state(robot_state(['x', 'c', 'a', 'b'], [9.0, 3.0, 1.0, 2.0]))
    assert mc.arm_values(given, arm, None).tolist() == [1.0, 2.0, 3.0]
    current = JointState(name=['a', 'b', 'c', 'x'], position=[7.0, 8.0, 6.0, 0.0])
    diff = mc.given_state(robot_state(['b'], [5.0], is_diff=True))
    assert mc.arm_values(diff, arm, current).tolist() == [7.0, 5.0, 6.0]
    empty = mc.given_state(robot_state([], []))
    assert mc.arm_values(empty, arm, current).tolist() == [7.0, 8.0, 6.0]
    assert mc.arm_values(empty, arm, None) is None
    partial = mc.given_state(robot_state(['a'], [1.0]))
    for state, cur in ((partial, current), (diff, None)):
        with pytest.raises(mc.MoveItRefusal) as refused:
            mc.arm_values(state, arm, cur)
        assert refused.value.code == E.INVALID_ROBOT_STATE
    bad = [robot_state(['a', 'b'], [1.0]), robot_state(['a', 'a'], [1.0, 1.0]),
           robot_state([f'j{i}' for i in range(10_000)], np.zeros(10_000))]
    for state in bad:
        with pytest.raises(mc.MoveItRefusal) as refused:
            mc.given_state(state)
        assert refused.value.code == E.INVALID_ROBOT_STATE
    with pytest.raises(mc.MoveItRefusal):
        mc.arm_values(mc.given_state(robot_state(arm, [1.0, float('nan'), 0.0])), arm, None)


def test_solution_state_keeps_the_request_joints():
    """The answer lists the request's joints in its order, values as given but the arm's."""
    given = mc.given_state(robot_state(['f1', 'b', 'f2'], [0.01, 9.0, 0.02]))
    out = mc.solution_state(given, ['a', 'b'], np.array([1.5, 2.5]), Header(frame_id='base'),
                            RobotState())
    assert list(out.joint_state.name) == ['f1', 'b', 'f2', 'a']
    assert list(out.joint_state.position) == [0.01, 2.5, 0.02, 1.5]
    assert out.joint_state.header.frame_id == 'base' and not out.is_diff


def test_regions_orientations_and_ranges():
    """Regions contain their inside only; orientation errors per axis; range costs and checks."""
    box = Region('box', (0.2, 0.4, 0.6), Transform(np.eye(3), np.array([1.0, 0.0, 0.0])))
    assert box.contains([1.09, 0.19, -0.29]) and not box.contains([1.11, 0.0, 0.0])
    cyl = Region('cylinder', (0.2, 0.1), Transform(np.eye(3), np.zeros(3)))
    assert cyl.contains([0.07, 0.07, 0.09]) and not cyl.contains([0.08, 0.08, 0.0])
    ball = Region('sphere', (0.5,), Transform(np.eye(3), np.zeros(3)))
    assert ball.contains([0.3, 0.4, 0.0]) and not ball.contains([0.3, 0.41, 0.0])
    with pytest.raises(InvalidConstraint):
        Region('cone', (1.0, 1.0), Transform(np.eye(3), np.zeros(3)))
    rule = OrientationRule('tip', np.eye(3), np.array([0.1, 0.1, 0.1]))
    tilt = Rotation.from_euler('XYZ', [0.05, -0.02, 0.3]).as_matrix()
    assert np.allclose(rule.error(tilt), [0.05, 0.02, 0.3], atol=1e-12)
    rules = GoalConstraints(np.array([-np.inf, 0.0]), np.array([np.inf, 1.0]),
                            others={'f': (0.0, 0.01)})
    assert rules.bounds_joints and not rules.empty
    assert rules.violation(np.array([5.0, 0.5]), ['a', 'b'], None, {'f': 0.005}) is None
    assert 'b' in rules.violation(np.array([5.0, 1.5]), ['a', 'b'], None, {'f': 0.005})
    assert 'f' in rules.violation(np.array([5.0, 0.5]), ['a', 'b'], None, {'f': 0.02})
    cost = JointRangeCost(None, rules.lower, rules.upper)
    assert cost(np.array([[3.0, 0.5], [3.0, 1.5]])).tolist() == [0.0, 500.0]


def test_constraint_messages(ur5, ur5_frames):
    """Unknown joints, meshes, visibility and foreign frames are refused, each with its reason."""
    arm = list(ur5.joint_names)
    given = mc.given_state(robot_state(arm + ['gripper'], np.zeros(len(arm) + 1)))
    ok = Constraints(joint_constraints=[
        JointConstraint(joint_name=arm[1], position=0.5, tolerance_above=0.1,
                        tolerance_below=0.2),
        JointConstraint(joint_name='gripper', position=0.0, tolerance_above=0.1,
                        tolerance_below=0.1)])
    rules = mc.goal_constraints(ok, arm, ur5_frames, given)
    assert rules.lower[1] == pytest.approx(0.3) and rules.upper[1] == pytest.approx(0.6)
    assert rules.others == {'gripper': (-0.1, 0.1)}
    unknown = Constraints(joint_constraints=[JointConstraint(joint_name='nope')])
    region = PositionConstraint(link_name='tool0')
    region.constraint_region.meshes = [Mesh()]
    region.constraint_region.primitive_poses = [Pose()]
    region.constraint_region.primitives = [SolidPrimitive(type=SolidPrimitive.BOX,
                                                          dimensions=[1.0, 1.0, 1.0])]
    cases = [unknown, Constraints(position_constraints=[region]),
             Constraints(visibility_constraints=[VisibilityConstraint()])]
    for msg in cases:
        with pytest.raises(InvalidConstraint):
            mc.goal_constraints(msg, arm, ur5_frames, given)
    region.constraint_region.meshes = []
    region.header.frame_id = 'map'
    with pytest.raises(mc.MoveItRefusal) as refused:
        mc.goal_constraints(Constraints(position_constraints=[region]), arm, ur5_frames, given)
    assert refused.value.code == E.FRAME_TRANSFORM_FAILURE
    assert len(cases) == 3
