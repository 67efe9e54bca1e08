"""End to end: pose goal streams on ``~/goal``, answered by a real sik_node over DDS.

The node serves the bundled Panda with ``use_joint_states:=true`` and pose goals, and sends a
command to a ros2_control-style topic; a :class:`GoalStreamClient` streams goals along a smooth
circle with a simulated arm following the answers on ``joint_states``. Every successful answer's
first solution is checked by Pinocchio's forward kinematics.
"""

import math
import subprocess
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
import numpy as np
import pytest
from rcl_interfaces.srv import SetParameters
import rclpy
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory

import harness
from sik_interfaces.msg import IKSolutionArray
from sik_interfaces.srv import SolveIK
from sik_ros.ros.stream_client import circle_goals, GoalStreamClient, stream_report
from sik_ros.serving.stream import MAX_COMMAND_PERIOD
from sik_ros.solver import SelectiveIK

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(180)]

R = SolveIK.Response
COMMANDS = '/test_arm/commands'
STREAM_PARAMS = ['use_joint_states:=true', 'goal_use_orientation:=true',
                 'publish_markers:=false']


@pytest.fixture(scope='module')
def robot():
    """The bundled Panda's robot model (the node serves that bundle)."""
    return SelectiveIK.load('panda').robot


def start_node(extra, tmp_path_factory, env):
    """A sik_node on the bundled Panda with the stream parameters; its process."""
    log_path = tmp_path_factory.mktemp('sik_node_stream') / 'node.log'
    with open(log_path, 'wb') as log:
        proc = harness.launch_node(None, STREAM_PARAMS + list(extra), env=env, stdout=log,
                                   stderr=subprocess.STDOUT)
    proc.log_path = log_path
    return proc


@pytest.fixture(scope='module')
def node_proc(tmp_path_factory):
    """The node, commanding a forward_command_controller-style topic."""
    proc = start_node(['command_format:=float64_multi_array', f'command_topic:={COMMANDS}'],
                      tmp_path_factory, harness.ros_env())
    yield proc
    harness.stop_node(proc)


@pytest.fixture(scope='module')
def client(node_proc, robot):
    """A stream client following the answers, once the node is up."""
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    with GoalStreamClient(robot.joint_names, follow=True, frame_id=robot.base_frame) as c:
        service = c.node.create_client(SolveIK, '/sik_node/solve_ik')
        if not (harness.wait_for_service(c.node, service, node_proc, 90.0)
                and c.wait_for_node(20.0)):
            pytest.fail(f'sik_node did not come up:\n{node_proc.log_path.read_text()}')
        c.service = service
        yield c
    rclpy.shutdown()


def wait_future(future, timeout=10.0):
    """The result of a future that the client's own thread completes; None on timeout."""
    deadline = time.monotonic() + timeout
    while not future.done() and time.monotonic() < deadline:
        time.sleep(0.01)
    return future.result() if future.done() else None


def solve_ik(c, position, orientation):
    """One ~/solve_ik call from the client's node; its response (None if none came)."""
    request = harness.pose_request(position, orientation, 4)
    for _ in range(3):  # a new client's first reply may be dropped (sik_ros.ros.client)
        answer = wait_future(c.service.call_async(request), 5.0)
        if answer is not None:
            return answer
    return None


def set_params(c, **values):
    """Set sik_node parameters; every one must be accepted."""
    cli = c.node.create_client(SetParameters, '/sik_node/set_parameters')
    try:
        assert cli.wait_for_service(timeout_sec=10.0)
        request = SetParameters.Request(parameters=[
            Parameter(k, value=v).to_parameter_msg() for k, v in values.items()])
        result = wait_future(cli.call_async(request))
        assert result is not None and all(r.successful for r in result.results)
    finally:
        c.node.destroy_client(cli)


def circle(robot, count, rate):
    """Goals on a 10 cm circle through the tip at the middle of the ranges; its quaternion."""
    p, quat = robot.fk((robot.lower + robot.upper) / 2)
    return circle_goals(p, 0.10, count, 4.0, rate), quat


def test_stream_at_100hz_answered_in_order(client, robot):
    """A 100 Hz pose stream: nearly every goal answered, in order, each under its goal's stamp."""
    goals, quat = circle(robot, 300, 100.0)
    report = stream_report(client.run(goals, 100.0, quat, settle=1.0), fk=robot.fk)
    assert report['stamped'] >= 1 and report['unstamped'] == 0, report
    assert report['answered'] >= 0.9, report
    assert report['out_of_order'] == 0, report
    assert math.isfinite(report['last_answer']), 'the last goal was answered'
    assert report['checked'] == report['success'] >= 1, report
    assert report['success'] >= 0.95 * report['stamped'], report  # answered goals succeed
    assert report['invalid'] == 0 and report['flips'] == 0, report


def test_commands_follow_the_answers_within_the_velocity_limits(client, robot):
    """Each command has every joint, steps within velocity x period, and ends at the answer."""
    commands, answers = [], []
    sub = client.node.create_subscription(Float64MultiArray, COMMANDS, commands.append, 100)
    tap = client.node.create_subscription(IKSolutionArray, '/sik_node/solutions',
                                          answers.append, 1000)
    try:
        deadline = time.monotonic() + 10.0
        while sub.get_publisher_count() == 0 and time.monotonic() < deadline:
            time.sleep(0.05)
        goals, quat = circle(robot, 200, 100.0)
        client.run(goals, 100.0, quat, settle=1.0)
    finally:
        client.node.destroy_subscription(sub)
        client.node.destroy_subscription(tap)
    assert len(commands) >= 100, f'{len(commands)} commands for 200 goals'
    q = np.array([c.data for c in commands])
    assert q.shape[1] == len(robot.joint_names)
    assert np.all(q >= robot.lower - 1e-9) and np.all(q <= robot.upper + 1e-9)
    steps = np.abs(np.diff(q, axis=0))
    assert np.all(steps <= robot.velocity_limits * MAX_COMMAND_PERIOD + 1e-9)
    # the commands move: the tip goes round a 10 cm circle, so the arm travels, in most steps
    moving = np.max(steps, axis=1) > 1e-4
    assert moving.sum() >= 0.5 * len(steps), f'{moving.sum()} of {len(steps)} steps move'
    assert np.max(np.abs(q - q[0]), axis=0).max() >= 0.05, 'the commands never left the start'
    last = next(a for a in reversed(answers) if a.error_code == R.SUCCESS)
    assert np.allclose(q[-1], last.solutions[0].joint_state.position, atol=1e-9), \
        'small steps are commanded whole: the last command is the last answer'


def test_bad_goals_get_their_codes_under_their_stamps(client, robot):
    """NaN, a zero quaternion and an unknown frame: coded answers that carry the goal's stamp."""
    q0 = (robot.lower + robot.upper) / 2
    p, quat = robot.fk(q0)
    client.publish_state(q0)  # the simulated arm is at the goal's posture

    def nan(i, msg):
        msg.pose.position.x = float('nan')

    def zero_quaternion(i, msg):
        o = msg.pose.orientation
        o.x = o.y = o.z = o.w = 0.0

    def unknown_frame(i, msg):
        msg.header.frame_id = 'nowhere'

    for edit, code in ((nan, R.INVALID_GOAL), (zero_quaternion, R.INVALID_GOAL),
                       (unknown_frame, R.INVALID_FRAME)):
        record = client.run(p[None], 10.0, quat, settle=1.0, make_msg=edit)
        assert len(record.answers) == 1, edit.__name__
        answer = record.answers[0]
        assert answer.code == code, (edit.__name__, answer.message)
        assert answer.stamp_ns == record.stamps_ns[0]
        assert answer.message
    good = stream_report(client.run(p[None], 10.0, quat, settle=1.0), fk=robot.fk)
    assert good['success'] == good['checked'] == 1, 'a good goal after the bad ones'


def test_a_jump_is_flagged_and_not_followed(client, robot):
    """Over goal_max_joint_step from the seed: JOINT_JUMP with solutions, the seed kept."""
    q0 = (robot.lower + robot.upper) / 2
    p0, quat = robot.fk(q0)
    far, _ = robot.fk(q0 + np.array([0.6, 0.3, 0, 0.3, 0, 0, 0])[:len(q0)])
    set_params(client, goal_max_joint_step=0.05)
    client.publish_state(q0)
    try:
        first = client.run(p0[None], 10.0, quat, settle=1.0)
        jump = client.run(far[None], 10.0, quat, settle=1.0)
        back = client.run(p0[None] + [0, 0, 0.001], 10.0, quat, settle=1.0)
    finally:
        set_params(client, goal_max_joint_step=0.5)
    assert [a.code for a in first.answers] == [R.SUCCESS]
    assert [a.code for a in jump.answers] == [R.JOINT_JUMP], jump.answers[0].message
    assert jump.answers[0].q is not None, 'a jump still gives its solutions'
    assert 'goal_max_joint_step' in jump.answers[0].message
    assert [a.code for a in back.answers] == [R.SUCCESS], 'seeded by the answer before the jump'


def diagnostics_values(c, timeout=5.0):
    """The key/values of sik_node's next /diagnostics status."""
    got = []
    sub = c.node.create_subscription(DiagnosticArray, '/diagnostics', got.append, 10)
    try:
        deadline = time.monotonic() + timeout
        while not got and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        c.node.destroy_subscription(sub)
    assert got, 'no /diagnostics'
    return {kv.key: kv.value for kv in got[-1].status[0].values}


def test_burst_counted_and_services_answered(client, robot):
    """10,000 goals in a second: answers in order, the rest counted replaced; services answer."""
    before = diagnostics_values(client)
    goals, quat = circle(robot, 10000, 10000.0)
    answers = []
    call = threading.Thread(target=lambda: answers.append(solve_ik(client, goals[0], quat)))
    call.start()
    record = client.run(goals, 10000.0, quat, settle=2.0)
    call.join()
    assert answers and answers[0] is not None and answers[0].error_code == R.SUCCESS
    report = stream_report(record, fk=robot.fk)
    assert report['out_of_order'] == 0 and report['unstamped'] == 0, report
    assert report['invalid'] == 0, report
    after = diagnostics_values(client)
    received = int(after['goals received']) - int(before['goals received'])
    replaced = int(after['goals replaced']) - int(before['goals replaced'])
    assert 0 < received <= 10000
    assert received == replaced + report['answers'], (received, replaced, report['answers'])
    assert replaced == report['replaced_reported']


def test_a_vanishing_client_leaves_the_node_serving(client, robot):
    """A client that streams and disappears mid-stream: the node goes on answering."""
    q0 = (robot.lower + robot.upper) / 2
    p, quat = robot.fk(q0)
    client.publish_state(q0)
    other = rclpy.create_node('sik_stream_vanishing')
    pub = other.create_publisher(PoseStamped, '/sik_node/goal', 10)
    msg = PoseStamped()
    msg.header.frame_id = robot.base_frame
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(v) for v in p)
    o = msg.pose.orientation
    o.x, o.y, o.z, o.w = (float(v) for v in quat)
    for _ in range(200):
        pub.publish(msg)
    other.destroy_node()
    answer = solve_ik(client, p, quat)
    assert answer is not None and answer.error_code == R.SUCCESS
    good = stream_report(client.run(p[None] + [0, 0.001, 0], 10.0, quat, settle=1.0),
                         fk=robot.fk)
    assert good['success'] == good['checked'] == 1


def test_joint_trajectory_command(tmp_path_factory, robot):
    """command_format joint_trajectory: one point in the arm's joint order, timed by the period."""
    env = harness.ros_env()  # a graph of its own: the module's node runs meanwhile
    domain = int(env['ROS_DOMAIN_ID'])
    proc = start_node(['command_format:=joint_trajectory', f'command_topic:={COMMANDS}'],
                      tmp_path_factory, env)
    got = []
    context = rclpy.Context()
    try:
        rclpy.init(context=context, domain_id=domain,
                   signal_handler_options=SignalHandlerOptions.NO)
        with GoalStreamClient(robot.joint_names, follow=True, frame_id=robot.base_frame,
                              node_name='sik_stream_jtc', context=context) as c:
            sub = c.node.create_subscription(JointTrajectory, COMMANDS, got.append, 100)
            service = c.node.create_client(SolveIK, '/sik_node/solve_ik')
            assert harness.wait_for_service(c.node, service, proc, 90.0), \
                proc.log_path.read_text()
            assert c.wait_for_node(20.0)
            deadline = time.monotonic() + 10.0  # the command topic matched before the goals
            while sub.get_publisher_count() == 0 and time.monotonic() < deadline:
                time.sleep(0.05)
            c.publish_state((robot.lower + robot.upper) / 2)
            goals, quat = circle(robot, 100, 50.0)
            c.run(goals, 50.0, quat, settle=1.0)
            c.node.destroy_subscription(sub)
    finally:
        rclpy.try_shutdown(context=context)
        harness.stop_node(proc)
    assert len(got) >= 50, (f'{len(got)} trajectories for 100 goals; the node said:\n'
                            + proc.log_path.read_text()[-2000:])
    for traj in got:
        assert list(traj.joint_names) == list(robot.joint_names)
        assert len(traj.points) == 1
        t = traj.points[0].time_from_start
        assert 0 < t.sec + t.nanosec * 1e-9 <= MAX_COMMAND_PERIOD + 1e-9
        q = np.array(traj.points[0].positions)
        assert np.all(q >= robot.lower - 1e-9) and np.all(q <= robot.upper + 1e-9)


def test_stream_in_a_solver_process_of_its_own(tmp_path_factory, robot):
    """goal_solver_process: the stream solved in a process, answered in order and exact."""
    env = harness.ros_env()  # a graph of its own: the module's node runs meanwhile
    domain = int(env['ROS_DOMAIN_ID'])
    proc = start_node(['goal_solver_process:=true'], tmp_path_factory, env)
    context = rclpy.Context()
    try:
        rclpy.init(context=context, domain_id=domain,
                   signal_handler_options=SignalHandlerOptions.NO)
        with GoalStreamClient(robot.joint_names, follow=True, frame_id=robot.base_frame,
                              node_name='sik_stream_process', context=context) as c:
            service = c.node.create_client(SolveIK, '/sik_node/solve_ik')
            assert harness.wait_for_service(c.node, service, proc, 120.0), \
                proc.log_path.read_text()
            assert c.wait_for_node(20.0)
            c.publish_state((robot.lower + robot.upper) / 2)
            goals, quat = circle(robot, 150, 50.0)
            report = stream_report(c.run(goals, 50.0, quat, settle=1.0), fk=robot.fk)
    finally:
        rclpy.try_shutdown(context=context)
        harness.stop_node(proc)
    log = proc.log_path.read_text()
    assert '~/goal in a solver process of its own' in log, log[-2000:]
    assert report['out_of_order'] == 0 and report['unstamped'] == 0, report
    assert report['answered'] >= 0.9, report
    assert report['checked'] == report['success'] >= 1, report
    assert report['invalid'] == 0 and report['flips'] == 0, report
