"""A hostile client against a real sik_node: every field of every request through bad values.

Each field of ``~/solve_ik`` and ``~/solve_path`` (and the ``~/goal`` topic, and the node's
parameters) gets NaN, infinities, 0, negatives, huge and tiny (1e-300) numbers, empty and
oversized values. Every request must get one answer with a code (no resend; a request left
unanswered for seconds beyond its timeout counts as a hang), every number in an answer must be
finite (a clearance may be +inf when no obstacle was given), trajectory times must strictly
increase, and the node must still answer afterwards.
"""

import copy
import math
import subprocess
import time

from geometry_msgs.msg import PoseStamped
import numpy as np
import pytest
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from shape_msgs.msg import SolidPrimitive

import harness
from sik_interfaces.msg import IKSolutionArray
from sik_interfaces.srv import SolveIK, SolvePath
from sik_ros.kinematics.robots import load_robot
from sik_ros.ros.conversions import ERROR_NAMES

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(600)]
NUMBERS = (math.nan, math.inf, -math.inf, 0.0, -1.0, -1e308, 1e308, 1e-300)
#: Slack beyond a request's own timeout before an unanswered request counts as a hang [s].
SLACK = 1.0
#: Further wait before the hang guard gives up on a request (DDS, a loaded machine) [s].
HANG_GUARD = 10.0
#: The node's default request timeout (config/panda.yaml), and the path timeout [s].
DEFAULT_TIMEOUT, PATH_TIMEOUT = 0.5, 2.0
Q0 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])


@pytest.fixture(scope='module')
def hostile(tiny_bundle, tmp_path_factory):
    """sik_node on the tiny bundle, clients of both services, the goal topic and parameters."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions
    env = harness.ros_env()
    log_path = tmp_path_factory.mktemp('hostile') / 'node.log'
    with open(log_path, 'wb') as log:
        proc = harness.launch_node(str(tiny_bundle), ['max_waypoints:=3000'], env=env,
                                   stdout=log, stderr=subprocess.STDOUT)
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('sik_hostile_client')
    ik = node.create_client(SolveIK, f'{harness.NODE}/solve_ik')
    path = node.create_client(SolvePath, f'{harness.NODE}/solve_path')
    params = node.create_client(SetParameters, f'{harness.NODE}/set_parameters')
    if not harness.wait_for_service(node, ik, proc, 90.0):
        pytest.fail(f'sik_node did not come up:\n{log_path.read_text()}')
    assert path.wait_for_service(timeout_sec=10.0) and params.wait_for_service(timeout_sec=10.0)
    yield {'node': node, 'ik': ik, 'path': path, 'params': params, 'proc': proc,
           'log': log_path, 'robot': load_robot('panda')}
    node.destroy_node()
    rclpy.shutdown()
    assert harness.stop_node(proc) == 0
    text = log_path.read_text()
    assert 'Traceback' not in text and 'INTERNAL_ERROR' not in text, text[-4000:]


def seconds(duration) -> float:
    """A Duration in seconds."""
    return duration.sec + duration.nanosec * 1e-9


def budget(request, default: float) -> float:
    """The hang guard of a request [s]: its timeout (or the default), slack and the guard."""
    given = seconds(request.timeout)
    return (given if 0 < given < 30 else default if given == 0 else 30.0) + SLACK + HANG_GUARD


def ask(h, client, request, default: float):
    """One try (no resend): the answer, with a known code other than INTERNAL_ERROR."""
    limit = budget(request, default)
    answer = harness.call(h['node'], client, request, limit, attempt=limit)
    assert answer is not None, f'no answer (hang guard: {limit:.1f} s)'
    assert answer.error_code in ERROR_NAMES, answer.error_code
    assert answer.error_code != SolveIK.Response.INTERNAL_ERROR, answer.message
    return answer


def finite_ik(answer, obstacles: bool) -> None:
    """Every number of a SolveIK answer is finite (clearance +inf only without obstacles)."""
    for s in answer.solutions:
        values = list(s.joint_state.position) + list(s.posture_index) + [
            s.position_error, s.orientation_error, s.score]
        assert np.all(np.isfinite(values)), values
        d = s.min_obstacle_distance
        assert math.isfinite(d) or (d == math.inf and not obstacles), d


def finite_path(answer, obstacles: bool) -> None:
    """Every number of a SolvePath answer is finite; times strictly increase."""
    assert math.isfinite(answer.fraction)
    for traj, m in zip(answer.trajectories, answer.metrics):
        times = [seconds(p.time_from_start) for p in traj.points]
        assert all(b > a for a, b in zip(times, times[1:])), times[:5]
        for p in traj.points:
            assert np.all(np.isfinite(p.positions)) and p.time_from_start.nanosec < 1e9
        values = [m.max_step, m.travel, m.max_position_error, m.max_orientation_error,
                  m.duration, m.cost]
        assert np.all(np.isfinite(values)), values
        d = m.min_obstacle_distance
        assert math.isfinite(d) or (d == math.inf and not obstacles), d


def ik_request(h) -> SolveIK.Request:
    """A valid pose request with a seed and one box, to be spoiled field by field."""
    p, quat = h['robot'].fk(Q0)
    req = harness.pose_request(p, quat, 4)
    req.seed.name = list(h['robot'].joint_names)
    req.seed.position = Q0.tolist()
    prim, pose = harness.box((0.6, 0.6, 0.1), (0.1, 0.1, 0.1))
    req.obstacles, req.obstacle_poses = [prim], [pose]
    return req


def ik_variants(h):
    """(name, request) for every field of SolveIK spoiled in every way."""
    base = ik_request(h)
    out = []

    def variant(name, change):
        req = copy.deepcopy(base)
        change(req)
        out.append((name, req))
    for v in NUMBERS:
        for axis in 'xyz':
            variant(f'position.{axis}={v}', lambda r, a=axis, v=v: setattr(
                r.target.pose.position, a, v))
        for axis in 'xyzw':
            variant(f'orientation.{axis}={v}', lambda r, a=axis, v=v: setattr(
                r.target.pose.orientation, a, v))
        variant(f'seed[1]={v}', lambda r, v=v: r.seed.position.__setitem__(1, v))
        variant(f'obstacle dimension={v}', lambda r, v=v: setattr(
            r.obstacles[0], 'dimensions', [v, 0.1, 0.1]))
        variant(f'obstacle pose x={v}', lambda r, v=v: setattr(
            r.obstacle_poses[0].position, 'x', v))
        variant(f'obstacle quaternion w={v}', lambda r, v=v: setattr(
            r.obstacle_poses[0].orientation, 'w', v))
    variant('orientation all zero', lambda r: setattr(r.target.pose, 'orientation',
                                                      type(r.target.pose.orientation)(w=0.0)))
    variant('frame_id oversized', lambda r: setattr(r.target.header, 'frame_id', 'f' * 100000))
    variant('frame_id other', lambda r: setattr(r.target.header, 'frame_id', 'world'))
    for count in (0, 1, 2 ** 32 - 1):
        variant(f'max_solutions={count}', lambda r, c=count: setattr(r, 'max_solutions', c))
    variant('seed empty', lambda r: (setattr(r.seed, 'name', []),
                                     setattr(r.seed, 'position', [])))
    variant('seed oversized', lambda r: (setattr(r.seed, 'name', []), setattr(
        r.seed, 'position', [0.0] * 10000)))
    variant('seed names without positions', lambda r: setattr(r.seed, 'position', []))
    variant('seed name repeated', lambda r: r.seed.name.__setitem__(1, r.seed.name[0]))
    variant('seed name oversized', lambda r: r.seed.name.__setitem__(0, 'j' * 100000))
    variant('obstacle no dimensions', lambda r: setattr(r.obstacles[0], 'dimensions', []))
    variant('obstacle unknown type', lambda r: setattr(r.obstacles[0], 'type', 99))
    variant('obstacle cone', lambda r: setattr(r.obstacles[0], 'type', SolidPrimitive.CONE))
    variant('obstacles without poses', lambda r: setattr(r, 'obstacle_poses', []))
    variant('obstacles oversized', lambda r: (
        setattr(r, 'obstacles', r.obstacles * 10000),
        setattr(r, 'obstacle_poses', r.obstacle_poses * 10000)))
    for sec, nanosec in ((-1, 0), (-2 ** 31, 0), (0, 1), (0, 999_999_999), (2 ** 31 - 1, 0),
                         (0, 2 ** 32 - 1), (-1, 999_999_999)):
        variant(f'timeout=({sec}, {nanosec})', lambda r, s=sec, n=nanosec: (
            setattr(r.timeout, 'sec', s), setattr(r.timeout, 'nanosec', n)))
    variant('use_orientation false', lambda r: setattr(r, 'use_orientation', False))
    return out


def test_every_solve_ik_field_gets_a_code_in_time(hostile):
    """Spoiled SolveIK fields: a code in time, finite numbers, the node alive.

    In time: within the request's timeout + 11 s (``SLACK`` and the ``HANG_GUARD`` for DDS).
    """
    h = hostile
    variants = ik_variants(h)
    assert len(variants) > 90
    codes = {}
    for name, req in variants:
        answer = ask(h, h['ik'], req, DEFAULT_TIMEOUT)
        finite_ik(answer, bool(req.obstacles))
        codes[name] = ERROR_NAMES[answer.error_code]
    assert codes['position.x=nan'] == 'INVALID_GOAL'
    assert codes['timeout=(-1, 0)'] == 'INVALID_GOAL'
    assert codes['timeout=(0, 4294967295)'] == 'INVALID_GOAL'
    assert codes['seed[1]=nan'] == 'INVALID_SEED'
    assert codes['frame_id other'] == 'INVALID_FRAME'
    assert codes['obstacles oversized'] == 'INVALID_GOAL'
    check_alive(h)


def path_request(h, n=12) -> SolvePath.Request:
    """A valid straight pose path from the tip at Q0, to be spoiled field by field."""
    p0, quat = h['robot'].fk(Q0)
    req = SolvePath.Request(use_orientation=True, velocity_scaling=0.5)
    for t in np.linspace(0, 0.1, n):
        w = PoseStamped()
        w.pose.position.x, w.pose.position.y, w.pose.position.z = map(float, p0 + [0, t, 0])
        o = w.pose.orientation
        o.x, o.y, o.z, o.w = map(float, quat)
        req.waypoints.append(w)
    req.seed.name, req.seed.position = list(h['robot'].joint_names), Q0.tolist()
    req.timeout.sec = 3
    return req


def path_variants(h):
    """(name, request) for every field of SolvePath spoiled in every way."""
    base = path_request(h)
    out = []

    def variant(name, change):
        req = copy.deepcopy(base)
        change(req)
        out.append((name, req))
    for v in NUMBERS:
        variant(f'waypoint x={v}', lambda r, v=v: setattr(r.waypoints[3].pose.position, 'x', v))
        variant(f'waypoint qw={v}', lambda r, v=v: setattr(
            r.waypoints[3].pose.orientation, 'w', v))
        variant(f'max_joint_step={v}', lambda r, v=v: setattr(r, 'max_joint_step', v))
        variant(f'velocity_scaling={v}', lambda r, v=v: setattr(r, 'velocity_scaling', v))
        variant(f'seed[2]={v}', lambda r, v=v: r.seed.position.__setitem__(2, v))
    for v in (1e-12, 1e-9, 1e-6, 1.0):
        variant(f'velocity_scaling={v}', lambda r, v=v: setattr(r, 'velocity_scaling', v))
    variant('no waypoints', lambda r: setattr(r, 'waypoints', []))
    variant('waypoints oversized', lambda r: setattr(r, 'waypoints', r.waypoints * 1000))
    variant('waypoint frame other', lambda r: setattr(r.waypoints[2].header, 'frame_id', 'map'))
    for count in (0, 1, 2 ** 32 - 1):
        variant(f'max_paths={count}', lambda r, c=count: setattr(r, 'max_paths', c))
    prim, pose = harness.box((0.6, 0.6, 0.1), (0.1, 0.1, 0.1))
    variant('obstacle nan', lambda r: (setattr(r, 'obstacles', [SolidPrimitive(
        type=SolidPrimitive.SPHERE, dimensions=[math.nan])]), setattr(r, 'obstacle_poses',
                                                                      [pose])))
    variant('obstacles without poses', lambda r: setattr(r, 'obstacles', [prim]))
    for sec, nanosec in ((-1, 0), (0, 1), (0, 2 ** 32 - 1), (2 ** 31 - 1, 0)):
        variant(f'timeout=({sec}, {nanosec})', lambda r, s=sec, n=nanosec: (
            setattr(r.timeout, 'sec', s), setattr(r.timeout, 'nanosec', n)))
    variant('use_orientation false', lambda r: setattr(r, 'use_orientation', False))
    return out


def test_every_solve_path_field_gets_a_code_in_time(hostile):
    """Spoiled SolvePath fields: a code in time, finite numbers, rising times.

    In time: within the request's timeout + 11 s (``SLACK`` and the ``HANG_GUARD`` for DDS).
    """
    h = hostile
    codes = {}
    for name, req in path_variants(h):
        answer = ask(h, h['path'], req, PATH_TIMEOUT)
        finite_path(answer, bool(req.obstacles))
        codes[name] = ERROR_NAMES[answer.error_code]
    assert codes['velocity_scaling=1e-300'] == 'INVALID_GOAL'
    assert codes['velocity_scaling=1e-12'] in ('INVALID_GOAL', 'SUCCESS')
    assert codes['velocity_scaling=nan'] == 'INVALID_GOAL'
    assert codes['timeout=(-1, 0)'] == 'INVALID_GOAL'
    assert codes['max_paths=4294967295'] == 'INVALID_GOAL'
    assert codes['waypoint frame other'] == 'INVALID_FRAME'
    assert codes['velocity_scaling=1.0'] == 'SUCCESS'
    check_alive(h)


def test_durations_carry_past_two_thousand_waypoints(hostile):
    """2,500 waypoints: trajectory times strictly increase across whole seconds."""
    h = hostile
    req = path_request(h, n=2500)
    req.timeout.sec = 20
    answer = ask(h, h['path'], req, PATH_TIMEOUT)
    assert answer.error_code == SolvePath.Response.SUCCESS, answer.message
    finite_path(answer, False)
    times = [seconds(p.time_from_start) for p in answer.trajectories[0].points]
    assert times[-1] >= 2.0


def test_hostile_goals_on_the_topic_get_coded_answers(hostile):
    """Goals with NaN, inf and huge values on ~/goal: each answered with a code, or replaced."""
    import rclpy
    h = hostile
    node = h['node']
    got = []
    sub = node.create_subscription(IKSolutionArray, f'{harness.NODE}/solutions', got.append, 50)
    pub = node.create_publisher(PoseStamped, f'{harness.NODE}/goal', 50)
    deadline = time.monotonic() + 10.0
    while (pub.get_subscription_count() == 0 or sub.get_publisher_count() == 0) \
            and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.05)
    sent = 0
    for v in NUMBERS:
        msg = PoseStamped()
        msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = v, 0.0, 0.4
        pub.publish(msg)
        sent += 1
    deadline = time.monotonic() + sent * (DEFAULT_TIMEOUT + SLACK) + HANG_GUARD
    while (len(got) + sum(a.goals_replaced for a in got) < sent
           and time.monotonic() < deadline):
        rclpy.spin_once(node, timeout_sec=0.05)
    node.destroy_subscription(sub)
    node.destroy_publisher(pub)
    # the newest goal wins: each goal is answered, or counted in the next answer as replaced
    assert len(got) >= 1
    assert len(got) + sum(a.goals_replaced for a in got) == sent
    for answer in got:
        assert answer.error_code in ERROR_NAMES and \
            answer.error_code != SolveIK.Response.INTERNAL_ERROR, answer.message
        finite_ik(answer, False)
        assert math.isfinite(answer.joint_step)
    check_alive(h)


def set_parameter(h, name, value):
    """Try to set a parameter; whether the node accepted it (it must answer either way)."""
    if isinstance(value, bool):
        pv = ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=value)
    elif isinstance(value, int):
        pv = ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=value)
    elif isinstance(value, float):
        pv = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)
    else:
        pv = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value)
    answer = harness.call(h['node'], h['params'], SetParameters.Request(
        parameters=[Parameter(name=name, value=pv)]), 10.0)
    assert answer is not None, f'no answer to setting {name}={value!r}'
    return answer.results[0].successful


def test_hostile_parameter_values_are_refused(hostile):
    """Bad parameter values are refused with a reason and the node still answers."""
    h = hostile
    floats = ('position_tolerance', 'orientation_tolerance', 'timeout', 'path_timeout')
    for name in floats:
        for v in NUMBERS:
            if set_parameter(h, name, v):
                assert math.isfinite(v) and v > 0, (name, v)
        for v in (2 ** 62, 'text', True):
            assert not set_parameter(h, name, v), (name, v)
    for name in ('num_solutions', 'max_solutions_cap', 'max_obstacles', 'max_waypoints'):
        for v in (-1, 2 ** 62, math.nan, 'text'):
            assert not set_parameter(h, name, v), (name, v)
    assert set_parameter(h, 'position_tolerance', 1e-4)
    assert set_parameter(h, 'orientation_tolerance', 1e-3)
    assert set_parameter(h, 'timeout', DEFAULT_TIMEOUT)
    assert set_parameter(h, 'path_timeout', PATH_TIMEOUT)
    check_alive(h)


def check_alive(h):
    """The node is running and answers a valid request."""
    assert h['proc'].poll() is None, h['log'].read_text()[-3000:]
    answer = ask(h, h['ik'], ik_request(h), DEFAULT_TIMEOUT)
    assert answer.error_code in (SolveIK.Response.SUCCESS, SolveIK.Response.NO_SOLUTION,
                                 SolveIK.Response.TIMEOUT), answer.message
