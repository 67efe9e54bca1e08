"""End to end: ``~/solve_path`` over real ROS 2 returns timed joint trajectories."""

import subprocess

from geometry_msgs.msg import PoseStamped
import numpy as np
import pytest
import rclpy
from rclpy.signals import SignalHandlerOptions

import harness
from sik_interfaces.srv import SolvePath
from sik_ros.kinematics.robots import load_robot

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(180)]
R = SolvePath.Response
Q0 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])


@pytest.fixture(scope='module')
def served(tmp_path_factory):
    """sik_node on the bundled Panda model and a SolvePath client."""
    env = harness.ros_env()
    log_path = tmp_path_factory.mktemp('path_node') / 'node.log'
    with open(log_path, 'wb') as log:
        proc = harness.launch_node(None, env=env, stdout=log, stderr=subprocess.STDOUT)
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('sik_path_test')
    client = node.create_client(SolvePath, '/sik_node/solve_path')
    if not harness.wait_for_service(node, client, proc, 90.0):
        pytest.fail(f'sik_node did not come up:\n{log_path.read_text()}')
    yield node, client
    node.destroy_node()
    rclpy.shutdown()
    harness.stop_node(proc)


def path_request(robot, n=20, length=0.2, frame='', scaling=0.5, step=0.0):
    """A straight line of tool poses from the tip at Q0, the orientation held."""
    p0, quat = robot.fk(Q0)
    req = SolvePath.Request(use_orientation=True, max_joint_step=step, velocity_scaling=scaling)
    for t in np.linspace(0, length, n):
        w = PoseStamped()
        w.header.frame_id = frame
        p = p0 + [0.0, t, 0.0]
        w.pose.position.x, w.pose.position.y, w.pose.position.z = map(float, p)
        w.pose.orientation.x, w.pose.orientation.y, w.pose.orientation.z, \
            w.pose.orientation.w = map(float, quat)
        req.waypoints.append(w)
    req.seed.name = list(robot.joint_names)
    req.seed.position = Q0.tolist()
    req.timeout.sec = 5
    return req


def test_solve_path_returns_trajectories_within_the_velocity_limits(served):
    """A line: SUCCESS, ranked trajectories whose times respect the scaled velocity limits."""
    node, client = served
    robot = load_robot('panda')
    answer = harness.call(node, client, path_request(robot), 30.0)
    assert answer.error_code == R.SUCCESS, answer.message
    assert answer.fraction == 1.0 and len(answer.trajectories) == len(answer.metrics) >= 1
    costs = [m.cost for m in answer.metrics]
    assert costs == sorted(costs)
    p0, _ = robot.fk(Q0)
    for traj, m in zip(answer.trajectories, answer.metrics):
        assert list(traj.joint_names) == robot.joint_names and len(traj.points) == 20
        q = np.array([pt.positions for pt in traj.points])
        t = np.array([pt.time_from_start.sec + pt.time_from_start.nanosec * 1e-9
                      for pt in traj.points])
        assert t[0] == 0 and np.all(np.diff(t) > 0)
        speed = np.abs(np.diff(q, axis=0)) / np.diff(t)[:, None]
        assert np.all(speed <= 0.5 * robot.velocity_limits + 1e-6)
        assert m.duration == pytest.approx(t[-1], abs=1e-6)
        assert m.max_step <= 0.3 and m.max_position_error <= 1e-4
        for k in (0, 19):
            reached, _ = robot.fk(q[k])
            assert np.linalg.norm(reached - (p0 + [0.0, 0.2 * k / 19, 0.0])) <= 1e-4


@pytest.mark.parametrize('change, code', [
    (lambda r: r.waypoints.clear(), R.INVALID_GOAL),
    (lambda r: setattr(r, 'max_joint_step', -0.1), R.INVALID_GOAL),
    (lambda r: setattr(r, 'velocity_scaling', 2.0), R.INVALID_GOAL),
    (lambda r: setattr(r.waypoints[3].header, 'frame_id', 'world_x'), R.INVALID_FRAME),
    (lambda r: setattr(r.waypoints[2].pose.position, 'x', float('nan')), R.INVALID_GOAL),
])
def test_bad_path_requests_get_their_codes(served, change, code):
    """Empty, negative, out-of-range, wrong-frame or NaN input: its code and a message."""
    node, client = served
    req = path_request(load_robot('panda'), n=5)
    change(req)
    answer = harness.call(node, client, req, 30.0)
    assert answer.error_code == code and answer.message, answer.message
    assert not answer.trajectories
