"""End to end: MoveIt's /compute_ik and /compute_fk on a real sik_node with the bundled Panda.

Requests are built as MoveIt user code builds them for move_group (group ``panda_arm``, the
whole robot's state with the finger joints as seed, a 50 ms timeout) and every answer is checked
by an independent forward kinematics: Pinocchio on example-robot-data's whole Panda model (nine
joints, fingers included), not sik_ros's kinematics.
"""

import time

from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Pose, PoseStamped
from moveit_msgs.msg import (Constraints, JointConstraint, MoveItErrorCodes as E,
                             OrientationConstraint, PositionConstraint)
from moveit_msgs.srv import GetPositionFK, GetPositionIK
import numpy as np
import pinocchio as pin
import pytest
from rcl_interfaces.srv import SetParameters
import rclpy
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from shape_msgs.msg import SolidPrimitive

import harness
from sik_ros.kinematics.collision import CollisionChecker

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(180)]

ARM = [f'panda_joint{i}' for i in range(1, 8)]
FINGERS = ['panda_finger_joint1', 'panda_finger_joint2']
POS_TOL, ROT_TOL = 1e-4, 1e-3        # config/panda.yaml
MOVEIT_TIMEOUT = Duration(sec=0, nanosec=50_000_000)


class PandaFK:
    """Independent FK: example-robot-data's whole Panda in Pinocchio (fingers included)."""

    def __init__(self):
        import example_robot_data
        self.model = example_robot_data.load('panda').model
        self.data = self.model.createData()
        self.lower = self.model.lowerPositionLimit.copy()
        self.upper = self.model.upperPositionLimit.copy()

    def q(self, names, positions):
        """A configuration of the whole model from joint names and values."""
        q = pin.neutral(self.model)
        for name, value in zip(names, positions):
            q[self.model.joints[self.model.getJointId(name)].idx_q] = value
        return q

    def place(self, q, link):
        """Pose (SE3) of ``link`` in panda_link0."""
        pin.framesForwardKinematics(self.model, self.data, q)
        base = self.data.oMf[self.model.getFrameId('panda_link0')]
        return base.actInv(self.data.oMf[self.model.getFrameId(link)])


@pytest.fixture(scope='module')
def fk():
    """The independent FK."""
    return PandaFK()


@pytest.fixture(scope='module')
def ros(tmp_path_factory):
    """A sik_node with the bundled Panda (config/panda.yaml) and a client node, once up."""
    with harness.node_with_clients(
            tmp_path_factory, 'moveit_user',
            {'ik': (GetPositionIK, '/compute_ik'), 'fk': (GetPositionFK, '/compute_fk')}) as node:
        yield node


def call(node, client, request):
    """One answer (resent if a reply is lost); fails the test when none comes."""
    answer = harness.call(node, client, request, timeout=20.0, attempt=2.0)
    assert answer is not None, 'no answer'
    return answer


def state(names, positions):
    """A JointState of names and positions."""
    return JointState(name=list(names), position=[float(v) for v in positions])


def pose_of(placement):
    """An SE3 as a geometry_msgs Pose."""
    x, y, z, w = pin.Quaternion(placement.rotation).coeffs()
    p = placement.translation
    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in p)
    pose.orientation.x, pose.orientation.y = float(x), float(y)
    pose.orientation.z, pose.orientation.w = float(z), float(w)
    return pose


def ik_request(goal_pose, seed_names, seed_positions, frame='panda_link0', group='panda_arm',
               timeout=MOVEIT_TIMEOUT, link='', constraints=None):
    """A GetPositionIK request as MoveIt user code fills it."""
    req = GetPositionIK.Request()
    ik = req.ik_request
    ik.group_name = group
    ik.robot_state.joint_state = state(seed_names, seed_positions)
    ik.avoid_collisions = True
    ik.ik_link_name = link
    ik.pose_stamped = PoseStamped(pose=goal_pose)
    ik.pose_stamped.header.frame_id = frame
    ik.timeout = timeout
    if constraints is not None:
        ik.constraints = constraints
    return req


@pytest.fixture(scope='module')
def free(panda):
    """Whether arm configurations (N, 7) are free of self-collision (the Panda's SRDF)."""
    checker = CollisionChecker(panda)
    return lambda qs: ~checker.self_collision(qs)


def reachable(fk, rng, count, free=None):
    """Arm configurations (count, 7) within the limits, and their tool poses (independent FK).

    With ``free``, only configurations free of self-collision.
    """
    lo, hi = fk.lower[:7], fk.upper[:7]
    qs = rng.uniform(lo + 0.05, hi - 0.05, size=(4 * count, 7))
    qs = (qs[free(qs)] if free is not None else qs)[:count]
    assert len(qs) == count
    return qs, [fk.place(fk.q(ARM, q), 'panda_hand_tcp') for q in qs]


def check_solution(fk, answer, req, goal, link='panda_hand_tcp'):
    """The answer's state: the request's joints as given, arm within limits, on the goal."""
    sol = answer.solution.joint_state
    given = req.ik_request.robot_state.joint_state
    assert list(sol.name[:len(given.name)]) == list(given.name)
    values = dict(zip(sol.name, sol.position))
    for name, value in zip(given.name, given.position):
        if name not in ARM:
            assert values[name] == value, name
    q = fk.q(sol.name, sol.position)
    arm = np.array([values[n] for n in ARM])
    assert np.all(arm >= fk.lower[:7] - 1e-9) and np.all(arm <= fk.upper[:7] + 1e-9)
    placed = fk.place(q, link)
    err = pin.log6(goal.actInv(placed)).vector
    return float(np.linalg.norm(placed.translation - goal.translation)), float(
        np.linalg.norm(err[3:]))


def test_hundred_moveit_goals_exact(ros, fk, free):
    """100 reachable pose goals as MoveIt user code asks them: >= 99 exact, none invalid.

    Reachable: the tool poses of postures within the limits and free of self-collision (the
    requests ask for collision-free answers).
    """
    rng = np.random.default_rng(50)
    qs, goals = reachable(fk, rng, 100, free)
    seeds = rng.uniform(fk.lower[:7] + 0.05, fk.upper[:7] - 0.05, size=(100, 7))
    exact = invalid = 0
    for seed, goal in zip(seeds, goals):
        names = FINGERS[:1] + ARM + FINGERS[1:]           # any order, fingers included
        positions = [0.021] + list(seed) + [0.034]
        req = ik_request(pose_of(goal), names, positions)
        answer = call(ros, ros.ik, req)
        assert answer.error_code.val in (E.SUCCESS, E.NO_IK_SOLUTION, E.TIMED_OUT), \
            answer.error_code.message
        if answer.error_code.val != E.SUCCESS:
            continue
        position_error, angle = check_solution(fk, answer, req, goal)
        if position_error <= POS_TOL and angle <= ROT_TOL:
            exact += 1
        else:
            invalid += 1
    assert invalid == 0
    assert exact >= 99


def test_bad_input_answered_with_codes(ros, fk):
    """Bad requests get MoveIt's codes and a message; the node answers the next request."""
    rng = np.random.default_rng(7)
    (q,), (goal,) = reachable(fk, rng, 1)
    names, seed = ARM + FINGERS, list(q + 0.1) + [0.02, 0.02]

    def request(**kw):
        return ik_request(kw.pop('pose', pose_of(goal)), kw.pop('names', names),
                          kw.pop('seed', seed), **kw)
    nan = pose_of(goal)
    nan.position.x = float('nan')
    zero = pose_of(goal)
    zero.orientation.x = zero.orientation.y = zero.orientation.z = zero.orientation.w = 0.0
    far = pose_of(goal)
    far.position.x = 3.0
    several = request()
    several.ik_request.ik_link_names = ['panda_hand_tcp', 'panda_link8']
    several.ik_request.pose_stamped_vector = [PoseStamped(pose=pose_of(goal))] * 2
    mismatched = request()
    mismatched.ik_request.robot_state.joint_state.position = seed[:-1]
    huge = request(names=[f'j{i}' for i in range(10_000)], seed=np.zeros(10_000))
    cases = [
        (request(group='manipulator'), E.INVALID_GROUP_NAME),
        (request(link='panda_leftfinger'), E.INVALID_LINK_NAME),
        (request(frame='camera_link'), E.FRAME_TRANSFORM_FAILURE),
        (request(pose=nan), E.INVALID_GOAL_CONSTRAINTS),
        (request(pose=zero), E.INVALID_GOAL_CONSTRAINTS),
        (request(pose=far), E.NO_IK_SOLUTION),
        (several, E.INVALID_LINK_NAME),
        (mismatched, E.INVALID_ROBOT_STATE),
        (huge, E.INVALID_ROBOT_STATE),
        (request(timeout=Duration(sec=0, nanosec=1)), E.TIMED_OUT),
        (request(names=ARM[:3], seed=q[:3]), E.INVALID_ROBOT_STATE),
    ]
    assert len(cases) == 11
    for req, code in cases:
        answer = call(ros, ros.ik, req)
        assert answer.error_code.val == code, (code, answer.error_code.message)
        assert answer.error_code.message and answer.error_code.source == 'sik_node'
        assert not answer.solution.joint_state.name
        ok = call(ros, ros.ik, request())
        assert ok.error_code.val == E.SUCCESS, ok.error_code.message


def joint_constraint(name, position, below, above):
    """A JointConstraint of weight 1."""
    return JointConstraint(joint_name=name, position=float(position), tolerance_below=below,
                           tolerance_above=above, weight=1.0)


def test_constraints_bound_and_check_the_answer(ros, fk, free):
    """Joint ranges bound the answer, an impossible one is not SUCCESS; regions are checked.

    Ranges of 0.3 rad about joints 1 and 3 of the goal's own configuration, from a seed 0.8 rad
    away: the library answers 114 of 150 such goals (76 %) within the ranges in a second each,
    the rest GOAL_CONSTRAINTS_VIOLATED or NO_IK_SOLUTION; at least 10 of 16 here.
    """
    rng = np.random.default_rng(11)
    qs, goals = reachable(fk, rng, 16, free)
    names = ARM + FINGERS
    checked = 0
    for q, goal in zip(qs, goals):
        far_seed = list(np.clip(q + 0.8, fk.lower[:7], fk.upper[:7])) + [0.02, 0.02]
        # a range about the generating posture's joints 1 and 3: the answer must lie in it
        rules = Constraints(joint_constraints=[joint_constraint(ARM[0], q[0], 0.15, 0.15),
                                               joint_constraint(ARM[2], q[2], 0.15, 0.15)])
        req = ik_request(pose_of(goal), names, far_seed, constraints=rules,
                         timeout=Duration(sec=1))
        answer = call(ros, ros.ik, req)
        if answer.error_code.val != E.SUCCESS:
            assert answer.error_code.val in (E.GOAL_CONSTRAINTS_VIOLATED, E.NO_IK_SOLUTION)
            continue
        position_error, angle = check_solution(fk, answer, req, goal)
        assert position_error <= POS_TOL and angle <= ROT_TOL
        got = dict(zip(answer.solution.joint_state.name, answer.solution.joint_state.position))
        assert abs(got[ARM[0]] - q[0]) <= 0.15 + 1e-9 and abs(got[ARM[2]] - q[2]) <= 0.15 + 1e-9
        checked += 1
    assert checked >= 10
    q, goal = qs[0], goals[0]
    seed = list(q) + [0.02, 0.02]
    impossible = Constraints(joint_constraints=[joint_constraint(ARM[0], 10.0, 0.01, 0.01)])
    answer = call(ros, ros.ik, ik_request(pose_of(goal), names, seed, constraints=impossible))
    assert answer.error_code.val == E.GOAL_CONSTRAINTS_VIOLATED, answer.error_code.message
    inside, outside = (PositionConstraint(link_name='panda_hand_tcp', weight=1.0)
                       for _ in range(2))
    for rule, offset in ((inside, 0.0), (outside, 0.5)):
        rule.header.frame_id = 'panda_link0'
        box = pin.SE3(np.eye(3), goal.translation + offset)
        rule.constraint_region.primitives = [SolidPrimitive(type=SolidPrimitive.BOX,
                                                            dimensions=[0.01, 0.01, 0.01])]
        rule.constraint_region.primitive_poses = [pose_of(box)]
    tilted = OrientationConstraint(link_name='panda_hand_tcp', weight=1.0,
                                   absolute_x_axis_tolerance=0.01,
                                   absolute_y_axis_tolerance=0.01,
                                   absolute_z_axis_tolerance=0.01)
    tilted.header.frame_id = 'panda_link0'
    tilted.orientation = pose_of(goal * pin.SE3(pin.rpy.rpyToMatrix(0.3, 0, 0),
                                                np.zeros(3))).orientation
    for rules, code in ((Constraints(position_constraints=[inside]), E.SUCCESS),
                        (Constraints(position_constraints=[outside]),
                         E.GOAL_CONSTRAINTS_VIOLATED),
                        (Constraints(orientation_constraints=[tilted]),
                         E.GOAL_CONSTRAINTS_VIOLATED)):
        answer = call(ros, ros.ik, ik_request(pose_of(goal), names, seed, constraints=rules))
        assert answer.error_code.val == code, answer.error_code.message


def test_link_fixed_to_the_tip(ros, fk):
    """A goal for panda_hand (fixed to the tool centre point) puts panda_hand there."""
    rng = np.random.default_rng(13)
    (q,), _ = reachable(fk, rng, 1)
    hand = fk.place(fk.q(ARM, q), 'panda_hand')
    req = ik_request(pose_of(hand), ARM, q + 0.05, link='panda_hand')
    answer = call(ros, ros.ik, req)
    assert answer.error_code.val == E.SUCCESS, answer.error_code.message
    position_error, angle = check_solution(fk, answer, req, hand, link='panda_hand')
    assert position_error <= POS_TOL and angle <= ROT_TOL


def test_compute_fk_exact(ros, fk):
    """/compute_fk places the chain's links as Pinocchio does; bad links and frames refused."""
    rng = np.random.default_rng(17)
    q = rng.uniform(fk.lower[:7], fk.upper[:7])
    links = ['panda_link0', 'panda_link3', 'panda_link7', 'panda_hand', 'panda_hand_tcp']
    for frame in ('', 'panda_link0'):
        req = GetPositionFK.Request(fk_link_names=links)
        req.header.frame_id = frame
        req.robot_state.joint_state = state(FINGERS + ARM, [0.01, 0.01] + list(q))
        answer = call(ros, ros.fk, req)
        assert answer.error_code.val == E.SUCCESS, answer.error_code.message
        assert list(answer.fk_link_names) == links and len(answer.pose_stamped) == len(links)
        for link, stamped in zip(links, answer.pose_stamped):
            assert stamped.header.frame_id == 'panda_link0'
            placed = fk.place(fk.q(ARM, q), link)
            p, o = stamped.pose.position, stamped.pose.orientation
            assert np.allclose([p.x, p.y, p.z], placed.translation, rtol=0, atol=1e-9)
            got = pin.Quaternion(o.w, o.x, o.y, o.z).toRotationMatrix()
            assert np.allclose(got, placed.rotation, rtol=0, atol=1e-9)
    for links, frame, code in ((['panda_leftfinger'], '', E.INVALID_LINK_NAME),
                               (['panda_link3'], 'map', E.FRAME_TRANSFORM_FAILURE)):
        req = GetPositionFK.Request(fk_link_names=links)
        req.header.frame_id = frame
        req.robot_state.joint_state = state(ARM, q)
        assert call(ros, ros.fk, req).error_code.val == code


def test_diff_state_takes_the_arm_from_joint_states(ros, fk, free):
    """A diff naming only the fingers is seeded by joint_states: the answer is that posture."""
    client = ros.create_client(SetParameters, '/sik_node/set_parameters')
    assert client.wait_for_service(timeout_sec=10.0)
    future = client.call_async(SetParameters.Request(
        parameters=[Parameter('use_joint_states', value=True).to_parameter_msg()]))
    rclpy.spin_until_future_complete(ros, future, timeout_sec=10.0)
    assert future.result() is not None and future.result().results[0].successful
    rng = np.random.default_rng(19)
    (q,), (goal,) = reachable(fk, rng, 1, free)
    publisher = ros.create_publisher(JointState, 'joint_states', 10)
    req = ik_request(pose_of(goal), FINGERS, [0.03, 0.03], timeout=Duration(sec=1))
    req.ik_request.robot_state.is_diff = True
    answer = None
    for _ in range(50):  # until the node's subscription is matched and has a state
        publisher.publish(state(ARM + FINGERS, list(q) + [0.0, 0.0]))
        answer = call(ros, ros.ik, req)
        if answer.error_code.val == E.SUCCESS:
            break
        assert answer.error_code.val == E.INVALID_ROBOT_STATE, answer.error_code.message
        time.sleep(0.1)
    assert answer.error_code.val == E.SUCCESS, answer.error_code.message
    position_error, angle = check_solution(fk, answer, req, goal)
    assert position_error <= POS_TOL and angle <= ROT_TOL
    got = dict(zip(answer.solution.joint_state.name, answer.solution.joint_state.position))
    assert np.abs(np.array([got[n] for n in ARM]) - q).max() < 1e-3
    assert list(answer.solution.joint_state.name) == FINGERS + ARM
