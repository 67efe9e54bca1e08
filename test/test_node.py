"""End to end: a real sik_node subprocess answering over DDS (docs/interfaces.md, section 4).

One node per module, on a random ROS_DOMAIN_ID (discovery on localhost), pointed at the tiny test
bundle with ``-p model_dir:=...``. A tiny model is not accurate, so answers are checked by FK of
the returned joint values against the returned errors and the tolerance semantics, not by how
well the model solves.
"""

import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
import time

from geometry_msgs.msg import PoseStamped
import numpy as np
import pytest
from rcl_interfaces.srv import SetParameters, SetParametersAtomically
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState
from visualization_msgs.msg import Marker, MarkerArray

import harness
from sik_interfaces.msg import IKSolution, IKSolutionArray
from sik_interfaces.srv import SolveIK
from sik_ros.kinematics.chain import chain_forward

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(120)]

R = SolveIK.Response
POS_TOL, ROT_TOL = 1e-4, 1e-3        # config/panda.yaml
BASE = 'panda_link0'
ANSWERED = (R.SUCCESS, R.NO_SOLUTION, R.TIMEOUT)
LONG = 5.0                            # request timeout that never cuts refinement short [s]


# -- fixtures -----------------------------------------------------------------------------------

@pytest.fixture(scope='module')
def bundle_dir(request):
    """The tiny test bundle (conftest's ``tiny_bundle``; else $SIK_TEST_BUNDLE)."""
    try:
        return str(request.getfixturevalue('tiny_bundle'))
    except pytest.FixtureLookupError:
        path = os.environ.get('SIK_TEST_BUNDLE')
        if not path or not (Path(path) / 'bundle.json').is_file():
            pytest.skip('no tiny_bundle fixture and no $SIK_TEST_BUNDLE')
        return path


@pytest.fixture(scope='module')
def ros_domain():
    """A random ROS_DOMAIN_ID for this module, for the node and this process alike."""
    saved = {k: os.environ.get(k) for k in ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE')}
    env = harness.ros_env()
    yield env
    for key, value in saved.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


@pytest.fixture(scope='module')
def node_proc(bundle_dir, ros_domain, tmp_path_factory):
    """The sik_node subprocess; its combined output goes to ``node_proc.log_path``."""
    log_path = tmp_path_factory.mktemp('sik_node') / 'node.log'
    with open(log_path, 'wb') as log:
        proc = harness.launch_node(bundle_dir, env=ros_domain, stdout=log,
                                   stderr=subprocess.STDOUT)
    proc.log_path = log_path
    yield proc
    harness.stop_node(proc)


@pytest.fixture(scope='module')
def ros(node_proc):
    """An rclpy client node with a SolveIK client, once the service is up."""
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('sik_node_test')
    client = node.create_client(SolveIK, '/sik_node/solve_ik')
    if not harness.wait_for_service(node, client, node_proc, 90.0):
        log = node_proc.log_path.read_text()
        node.destroy_node()
        rclpy.shutdown()
        pytest.fail(f'sik_node did not come up:\n{log}')
    node.solve_client = client
    yield node
    node.destroy_node()
    rclpy.shutdown()


@pytest.fixture(scope='module')
def goals(bundle_dir):
    """Goal kinds the bundle has models for."""
    return harness.bundle_goals(bundle_dir)


# -- helpers ------------------------------------------------------------------------------------

def solve(node, request, timeout=20.0):
    answer = harness.call(node, node.solve_client, request, timeout)
    assert answer is not None, 'no answer from sik_node'
    return answer


def target(panda, seed):
    """Joint values, tip position and quaternion of a random valid configuration."""
    q = np.random.default_rng(seed).uniform(panda.lower, panda.upper)
    p, quat = panda.fk(q)
    return q, p, quat


def request(position, orientation=None, max_solutions=0, timeout=LONG, frame_id=''):
    req = harness.pose_request(position, orientation, max_solutions, frame_id)
    req.timeout.sec, req.timeout.nanosec = int(timeout), int((timeout % 1) * 1e9)
    return req


def quat_angle(a, b):
    """Angle between unit quaternions (N, 4) x y z w and (4,) [rad]."""
    dot = np.abs(np.asarray(a) @ (np.asarray(b) / np.linalg.norm(b)))
    return 2 * np.arccos(np.clip(dot, -1.0, 1.0))


def check_answer(panda, answer, position, orientation=None):
    """Errors reported equal errors by FK (at least one solution); SUCCESS iff one is exact.

    Returns how many solutions were checked.
    """
    assert answer.error_code in ANSWERED, answer.message
    assert answer.message
    assert answer.solutions, f'no solution to verify ({answer.message})'
    within = []
    for s in answer.solutions:
        assert list(s.joint_state.name) == list(panda.joint_names)
        assert s.joint_state.header.frame_id == BASE
        q = np.array(s.joint_state.position)
        assert np.all(q >= panda.lower - 1e-9) and np.all(q <= panda.upper + 1e-9)
        p, quat = panda.fk_batch(q[None])
        assert np.linalg.norm(p[0] - position) == pytest.approx(s.position_error, abs=1e-7)
        ok = s.position_error <= POS_TOL
        if orientation is None:
            assert s.orientation_error == 0.0
        else:
            assert quat_angle(quat, orientation)[0] == pytest.approx(s.orientation_error,
                                                                     abs=1e-5)
            ok &= s.orientation_error <= ROT_TOL
        assert len(s.posture_index) > 0
        within.append(ok)
    assert (answer.error_code == R.SUCCESS) == any(within), answer.message
    families = {s.family for s in answer.solutions if s.family != IKSolution.NO_FAMILY}
    if answer.error_code == R.SUCCESS:
        assert within[0], 'the best-ranked solution must be within tolerance'
        assert answer.num_families >= max(1, len(families)), answer.message
        assert f'{answer.num_families} posture families' in answer.message
    elif answer.error_code == R.NO_SOLUTION:
        assert answer.num_families == 0 and not families
    return len(within)


def set_parameters(node, params, atomically=False):
    """Results (successful, reason) of setting parameters on sik_node."""
    kind = SetParametersAtomically if atomically else SetParameters
    service = 'set_parameters_atomically' if atomically else 'set_parameters'
    client = node.create_client(kind, f'/sik_node/{service}')
    try:
        assert client.wait_for_service(timeout_sec=10.0)
        req = kind.Request(parameters=[Parameter(k, value=v).to_parameter_msg()
                                       for k, v in params.items()])
        future = client.call_async(req)
        rclpy.spin_until_future_complete(node, future, timeout_sec=10.0)
        result = future.result()
        assert result is not None
        results = [result.result] if atomically else list(result.results)
        return [(r.successful, r.reason) for r in results]
    finally:
        node.destroy_client(client)


def spin_until(node, predicate, timeout, step=None):
    """Spin ``node`` until ``predicate()`` [s]; ``step()`` is called before each wait."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if step is not None:
            step()
        end = time.monotonic() + 0.5
        while time.monotonic() < end:
            if predicate():
                return True
            rclpy.spin_once(node, timeout_sec=0.05)
    return predicate()


# -- answers ------------------------------------------------------------------------------------

def test_position_goals_verified_by_fk(ros, panda):
    """Position goals at FK of random configurations: reported errors equal FK errors."""
    codes = []
    for seed in range(4):
        _, p, _ = target(panda, seed)
        answer = solve(ros, request(p))
        assert check_answer(panda, answer, p) >= 1
        codes.append(answer.error_code)
    assert R.SUCCESS in codes, 'no reachable position goal was solved'


def test_pose_goal_verified_by_fk(ros, panda, goals):
    """A pose goal: position and orientation errors equal those of the solutions' FK."""
    if 'pose' not in goals:
        pytest.skip('the bundle has no pose model')
    _, p, quat = target(panda, 10)
    answer = solve(ros, request(p, quat))
    assert check_answer(panda, answer, p, quat) >= 1


def test_solutions_are_ranked(ros, panda):
    """(tier, a family's first, score) non-decreasing, at most max_solutions, none repeated."""
    _, p, _ = target(panda, 1)
    answer = solve(ros, request(p, max_solutions=5))
    seen, ranks = set(), []
    for s in answer.solutions:
        ranks.append((s.tier, s.family in seen, s.score))
        seen.add(s.family)
    assert 1 <= len(ranks) <= 5
    assert ranks == sorted(ranks)
    q = np.array([s.joint_state.position for s in answer.solutions])
    assert len({tuple(np.round(row, 9)) for row in q}) == len(q)
    assert all(np.isinf(s.min_obstacle_distance) for s in answer.solutions)


def test_seed_matched_by_name(ros, panda):
    """A seed with shuffled joint names gives the same answer as the same seed in arm order."""
    q0, p, _ = target(panda, 2)
    order = np.random.default_rng(0).permutation(len(q0))
    named = request(p)
    named.seed.name = [panda.joint_names[i] for i in order]
    named.seed.position = [float(q0[i]) for i in order]
    plain = request(p)
    plain.seed.position = [float(v) for v in q0]
    a, b = solve(ros, named), solve(ros, plain)
    assert check_answer(panda, a, p) >= 1
    assert a.error_code == b.error_code
    assert [list(s.joint_state.position) for s in a.solutions] == \
        [list(s.joint_state.position) for s in b.solutions]
    assert [s.score for s in a.solutions] == [s.score for s in b.solutions]


def test_tier_order_holds_over_random_goals(ros, panda):
    """60 random goals (pose and position, half with a box at the elbow): tier order, always.

    Each answer's (tier, inexact, a family already in the answer) non-decreasing, and each
    tier what the solution reports (colliding: self-collision or no clearance).
    """
    rng = np.random.default_rng(41)
    mixed = 0
    for k in range(60):
        q = rng.uniform(panda.lower, panda.upper)
        p, quat = panda.fk(q)
        req = request(p, quat if k % 2 else None, max_solutions=16)
        if k % 4 >= 2:
            _, _, origins, _ = chain_forward(panda.chain, q[None], frames=True)
            elbow = origins[0, origins.shape[1] // 2]
            shape, pose = harness.box(tuple(elbow), (0.2, 0.2, 0.2))
            req.obstacles, req.obstacle_poses = [shape], [pose]
        answer = solve(ros, req)
        assert answer.error_code in ANSWERED
        seen, keys = set(), []
        for s in answer.solutions:
            colliding = s.self_collision or not s.min_obstacle_distance > 0
            converged = s.position_error <= POS_TOL and (k % 2 == 0 or
                                                         s.orientation_error <= ROT_TOL)
            assert s.tier == (2 if colliding else 0 if converged else 1)
            keys.append((s.tier, not converged, s.family in seen))
            seen.add(s.family)
        assert keys == sorted(keys), [key[0] for key in keys]
        mixed += len({key[0] for key in keys}) > 1
    assert mixed >= 3, 'the draws hold answers of several tiers'


def test_obstacles_report_clearance(ros, panda):
    """With a box obstacle every solution reports a finite clearance and is verified by FK."""
    _, p, _ = target(panda, 3)
    req = request(p)
    shape, pose = harness.box((0.5, 0.0, 0.3), (0.1, 0.1, 0.1))
    req.obstacles, req.obstacle_poses = [shape], [pose]
    answer = solve(ros, req)
    assert check_answer(panda, answer, p) >= 1
    assert answer.solutions and all(np.isfinite(s.min_obstacle_distance)
                                    for s in answer.solutions)
    assert 'collision-free' in answer.message


def test_topic_goal_answered_on_solutions(ros, panda):
    """A PoseStamped on ~/goal is answered on ~/solutions with FK-verified solutions."""
    _, p, _ = target(panda, 4)
    got = []
    sub = ros.create_subscription(IKSolutionArray, '/sik_node/solutions', got.append, 10)
    pub = ros.create_publisher(PoseStamped, '/sik_node/goal', 10)
    msg = PoseStamped()
    msg.header.frame_id = BASE
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(v) for v in p)
    try:
        assert spin_until(ros, lambda: pub.get_subscription_count() > 0
                          and sub.get_publisher_count() > 0, 10.0)
        assert spin_until(ros, lambda: bool(got), 10.0, step=lambda: pub.publish(msg))
    finally:
        ros.destroy_subscription(sub)
        ros.destroy_publisher(pub)
    answer = got[0]
    assert answer.header.frame_id == BASE
    assert check_answer(panda, answer, p) >= 1


def test_markers_published(ros, panda):
    """~/markers: a DELETEALL, the target, and per ranked solution a line strip to its FK tip."""
    _, p, _ = target(panda, 5)
    got = []
    sub = ros.create_subscription(MarkerArray, '/sik_node/markers', got.append, 10)
    answers = []
    try:
        assert spin_until(ros, lambda: sub.get_publisher_count() > 0, 10.0)
        assert spin_until(ros, lambda: bool(got), 10.0,
                          step=lambda: answers.append(solve(ros, request(p))))
    finally:
        ros.destroy_subscription(sub)
    answer, markers = answers[-1], got[-1].markers
    assert markers[0].action == Marker.DELETEALL
    assert any(m.ns == 'target' for m in markers)
    strips = [m for m in markers if m.type == Marker.LINE_STRIP]
    assert len(strips) == len(answer.solutions)
    assert [m.ns for m in strips] == [f'rank_{i:02d}' for i in range(len(strips))]
    assert all(strips[0].scale.x > m.scale.x for m in strips[1:]), 'best is highlighted'
    for strip, s in zip(strips, answer.solutions):
        assert strip.header.frame_id == BASE
        assert len(strip.points) == len(panda.joint_names) + 2
        tip = strip.points[-1]
        fk_tip, _ = panda.fk(np.array(s.joint_state.position))
        assert np.allclose([tip.x, tip.y, tip.z], fk_tip, atol=1e-9)


# -- error codes --------------------------------------------------------------------------------

def _bad_requests(panda):
    _, p, quat = target(panda, 6)
    q_mid = (panda.lower + panda.upper) / 2
    cases = {}
    req = request([float('nan'), 0.2, 0.3])
    cases['nan position'] = (req, R.INVALID_GOAL)
    req = request([0.3, float('inf'), 0.3])
    cases['inf position'] = (req, R.INVALID_GOAL)
    req = request(p, [0.0, 0.0, 0.0, 0.0])
    cases['zero quaternion'] = (req, R.INVALID_GOAL)
    req = request(p, frame_id='world')
    cases['unknown frame'] = (req, R.INVALID_FRAME)
    req = request(p)
    req.seed.position = [0.0, 0.1, 0.2]
    cases['seed of wrong length'] = (req, R.INVALID_SEED)
    req = request(p)
    req.seed.position = [float(v) for v in q_mid]
    req.seed.position[3] = 0.5  # panda_joint4 is in [-3.07, -0.07]
    cases['seed outside limits'] = (req, R.INVALID_SEED)
    req = request(p)
    req.seed.position = [float(v) for v in q_mid]
    req.seed.position[0] = float('nan')
    cases['non-finite seed'] = (req, R.INVALID_SEED)
    req = request(p)
    req.seed.name = list(panda.joint_names[:-1]) + ['elbow']
    req.seed.position = [float(v) for v in q_mid]
    cases['seed with an unknown joint'] = (req, R.INVALID_SEED)
    req = request(p)
    shape, _ = harness.box((0.5, 0, 0.3), (0.1, 0.1, 0.1))
    req.obstacles = [shape]
    cases['obstacle without pose'] = (req, R.INVALID_GOAL)
    return cases


@pytest.mark.parametrize('case', [
    'nan position', 'inf position', 'zero quaternion', 'unknown frame', 'seed of wrong length',
    'seed outside limits', 'non-finite seed', 'seed with an unknown joint',
    'obstacle without pose'])
def test_bad_request_gets_its_error_code(ros, panda, case):
    """Each kind of bad request is answered with its error code, a reason and no solutions."""
    req, code = _bad_requests(panda)[case]
    answer = solve(ros, req)
    assert answer.error_code == code, answer.message
    assert answer.message and not answer.solutions


def test_unreachable_target_is_no_solution(ros):
    """(5, 5, 5) m is out of reach: NO_SOLUTION within the budget, best-effort solutions listed.

    NO_SOLUTION, not TIMEOUT, says the search ended by itself before the 2 s budget ran out.
    """
    answer = solve(ros, request([5.0, 5.0, 5.0], timeout=2.0))
    assert answer.error_code == R.NO_SOLUTION, answer.message
    assert answer.solutions and all(s.position_error > 1.0 for s in answer.solutions)


def test_timeout_code(ros):
    """A 1 ns budget for an unreachable target ends as TIMEOUT, not NO_SOLUTION."""
    req = request([5.0, 5.0, 5.0])
    req.timeout.sec, req.timeout.nanosec = 0, 1
    answer = solve(ros, req)
    assert answer.error_code == R.TIMEOUT, answer.message


def test_huge_max_solutions_is_clamped(ros, panda):
    """max_solutions above the cap is clamped to max_solutions_cap, and the message says so."""
    _, p, _ = target(panda, 7)
    answer = solve(ros, request(p, max_solutions=1_000_000))
    assert answer.error_code in ANSWERED
    assert 'clamped' in answer.message and '64' in answer.message
    assert len(answer.solutions) <= 64


def test_node_still_answers_after_bad_requests(ros, panda, node_proc):
    """After every kind of bad request the node is alive and solves a valid goal."""
    for req, _ in _bad_requests(panda).values():
        solve(ros, req)
    _, p, _ = target(panda, 8)
    answer = solve(ros, request(p))
    assert check_answer(panda, answer, p) >= 1
    assert answer.solutions
    assert node_proc.poll() is None


# -- parameters ---------------------------------------------------------------------------------

@pytest.mark.parametrize('name, value', [
    ('num_solutions', 0), ('num_solutions', 65), ('max_solutions_cap', 0),
    ('position_tolerance', -1.0), ('orientation_tolerance', float('nan')), ('timeout', 0.0),
    ('model_dir', '/elsewhere'), ('num_solutions', 'many')])
def test_bad_parameter_rejected_with_reason(ros, name, value):
    """A bad parameter value (range, type, read-only) is rejected with a reason."""
    [(ok, reason)] = set_parameters(ros, {name: value})
    assert not ok and reason


def test_parameters_take_effect(ros, panda):
    """Accepted changes apply without a restart: the default count and the cap follow them."""
    _, p, _ = target(panda, 9)
    try:
        assert set_parameters(ros, {'num_solutions': 1}) == [(True, '')]
        assert len(solve(ros, request([5.0, 5.0, 5.0])).solutions) == 1
        [(ok, reason)] = set_parameters(ros, {'num_solutions': 2, 'max_solutions_cap': 3},
                                        atomically=True)
        assert ok, reason
        answer = solve(ros, request(p, max_solutions=10))
        assert 'clamped' in answer.message and 'max_solutions_cap=3' in answer.message
        assert len(answer.solutions) <= 3
    finally:
        [(ok, reason)] = set_parameters(ros, {'max_solutions_cap': 64, 'num_solutions': 16},
                                        atomically=True)
        assert ok, reason


def test_joint_states_seed(ros, panda):
    """With use_joint_states, the latest joint_states seeds a request that has no seed."""
    q0, p, _ = target(panda, 11)
    seeded = request(p)
    seeded.seed.name = list(panda.joint_names)
    seeded.seed.position = [float(v) for v in q0]
    expected = solve(ros, seeded)
    state = JointState(name=list(panda.joint_names) + ['panda_finger_joint1'],
                       position=[float(v) for v in q0] + [0.02])
    pub = ros.create_publisher(JointState, '/joint_states', 10)
    try:
        assert set_parameters(ros, {'use_joint_states': True}) == [(True, '')]
        assert spin_until(ros, lambda: pub.get_subscription_count() > 0, 10.0)
        answers = []

        def step():
            pub.publish(state)
            rclpy.spin_once(ros, timeout_sec=0.1)
            answers.append(solve(ros, request(p)))

        def same():
            return bool(answers) and [s.score for s in answers[-1].solutions] == \
                [s.score for s in expected.solutions]
        assert spin_until(ros, same, 10.0, step=step)
    finally:
        ros.destroy_publisher(pub)
        assert set_parameters(ros, {'use_joint_states': False}) == [(True, '')]


# -- concurrency and life cycle -----------------------------------------------------------------

def test_concurrent_clients(ros, panda):
    """Four clients calling at once each get correct answers for their own targets."""
    errors, done = [], []

    def client(k):
        node = rclpy.create_node(f'sik_node_test_client_{k}')
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        try:
            cli = node.create_client(SolveIK, '/sik_node/solve_ik')
            assert cli.wait_for_service(timeout_sec=10.0)
            for i in range(4):
                _, p, _ = target(panda, 100 + 10 * k + i)
                future = cli.call_async(request(p))
                executor.spin_until_future_complete(future, timeout_sec=20.0)
                answer = future.result()
                assert answer is not None, 'no answer'
                assert check_answer(panda, answer, p) >= 1
                done.append(k)
        except Exception as exc:  # collected and reported by the test thread
            errors.append(f'client {k}: {exc!r}')
        finally:
            executor.shutdown()
            node.destroy_node()

    threads = [threading.Thread(target=client, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60.0)
    assert not errors, errors
    assert len(done) == 16


@pytest.mark.parametrize('kind', ['missing', 'corrupt'])
def test_unusable_model_dir_exits_with_one_line(ros_domain, tmp_path, kind):
    """A missing or corrupt bundle: the node exits non-zero with one FATAL line, no traceback."""
    bundle = tmp_path / 'no_such_bundle'
    if kind == 'corrupt':
        bundle.mkdir()
        (bundle / 'bundle.json').write_text('{"kind": "sik_bundle", "models": ')
    proc = harness.launch_node(str(bundle), env=ros_domain, stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True)
    out, _ = proc.communicate(timeout=90)
    assert proc.returncode != 0
    lines = [line for line in out.splitlines() if line.strip()]
    assert len(lines) == 1 and 'FATAL' in lines[0] and 'no_such_bundle' in lines[0], out


def test_sigint_exits_cleanly(ros, node_proc):
    """SIGINT stops the node with exit code 0, and its log holds no traceback or error."""
    assert node_proc.poll() is None
    # generous wait: a loaded CI machine may take a while to tear down DDS
    assert harness.stop_node(node_proc, timeout=60.0) == 0
    log = node_proc.log_path.read_text()
    assert 'Traceback' not in log and '[ERROR]' not in log, log


def test_sigterm_exits_cleanly(ros, node_proc, bundle_dir, ros_domain):
    """SIGTERM stops a running node with exit code 0 (after the module's node has stopped)."""
    assert node_proc.poll() is not None, 'runs after test_sigint_exits_cleanly'
    proc = harness.launch_node(bundle_dir, env=ros_domain, stdout=subprocess.DEVNULL,
                               stderr=subprocess.STDOUT)
    try:
        assert harness.wait_for_service(ros, ros.solve_client, proc, 90.0)
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(60.0) == 0
    finally:
        harness.stop_node(proc)


def _solver_children(pid):
    """Process ids of a node's solver processes (its multiprocessing children)."""
    children = []
    for task in os.listdir(f'/proc/{pid}/task'):
        with open(f'/proc/{pid}/task/{task}/children') as f:
            children += [int(c) for c in f.read().split()]
    found = []
    for c in children:
        with open(f'/proc/{c}/cmdline', 'rb') as f:
            cmd = f.read().replace(b'\0', b' ').decode()
        if 'multiprocessing' in cmd and 'resource_tracker' not in cmd:
            found.append(c)
    return found


def test_solver_processes_answer_and_a_dead_one_is_replaced(ros, panda, node_proc, bundle_dir,
                                                            ros_domain, tmp_path):
    """With solver_processes:=2 the solves run in other processes, with the same answers.

    Answers are verified by FK; an error raised in a solver process keeps its code; a process
    killed while idle is replaced without failing anyone; processes that stop answering
    (SIGSTOP) cost answers within their deadline (TIMEOUT), are killed by the watchdog and
    replaced, and the node answers again. Runs after the module's node has stopped.
    """
    assert node_proc.poll() is not None, 'runs after test_sigint_exits_cleanly'
    log_path = tmp_path / 'node.log'
    log = open(log_path, 'w')
    proc = harness.launch_node(bundle_dir, ['solver_processes:=2'], env=ros_domain,
                               stdout=log, stderr=subprocess.STDOUT)

    def node_log():
        return log_path.read_text()[-3000:]

    def children(count):
        deadline = time.monotonic() + 90.0
        while time.monotonic() < deadline:
            found = _solver_children(proc.pid)
            if len(found) == count:
                return found
            time.sleep(0.2)
        return _solver_children(proc.pid)

    try:
        started = time.monotonic()
        assert harness.wait_for_service(ros, ros.solve_client, proc, 90.0)
        load_time = time.monotonic() - started  # a process's start-up, at most
        workers = children(2)
        assert len(workers) == 2, workers
        _, p, _ = target(panda, 41)
        assert check_answer(panda, solve(ros, request(p)), p) >= 1
        req, code = _bad_requests(panda)['seed outside limits']
        answer = solve(ros, req)
        assert answer.error_code == code and 'panda_joint4' in answer.message, answer.message
        os.kill(workers[0], signal.SIGKILL)  # idle: nobody's request fails
        for _ in range(3):
            answer = solve(ros, request(p))
            assert answer.error_code == R.SUCCESS, answer.message
        assert check_answer(panda, answer, p) >= 1
        # the replacement has loaded and joined the idle ones: the pool logs it as 'restarted'
        # (the wait's bound, a start-up and 60 s, guards against a hang)
        deadline = time.monotonic() + load_time + 60.0
        while 'restarted' not in log_path.read_text() and time.monotonic() < deadline:
            time.sleep(0.2)
        assert 'restarted' in log_path.read_text(), node_log()
        fresh = children(2)
        assert len(fresh) == 2 and workers[0] not in fresh, (workers, fresh)
        for pid in fresh:
            os.kill(pid, signal.SIGSTOP)  # stuck: the watchdog must answer for them
        # (solve() gives up after 20 s: a guard against a hang, not a speed claim)
        answer = solve(ros, request(p, timeout=1.0))
        assert answer.error_code == R.TIMEOUT, answer.message
        assert 'being replaced' in answer.message, answer.message  # the watchdog's answer
        for _ in range(120):  # each stuck one meets a request, times out and is replaced
            answer = solve(ros, request(p, timeout=1.0))
            assert answer.error_code in (R.SUCCESS, R.TIMEOUT), answer.message
            last = _solver_children(proc.pid)
            if answer.error_code == R.SUCCESS and not set(fresh) & set(last):
                break
            time.sleep(0.25)
        assert answer.error_code == R.SUCCESS, answer.message
        assert not set(fresh) & set(last), (fresh, last)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(60.0) == 0, node_log()
        deadline = time.monotonic() + 10.0
        while any(os.path.exists(f'/proc/{c}') for c in last) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not any(os.path.exists(f'/proc/{c}') for c in last), 'a solver outlived the node'
    finally:
        harness.stop_node(proc)
        log.close()


if __name__ == '__main__':  # pragma: no cover
    sys.exit(pytest.main([__file__, '-q']))
