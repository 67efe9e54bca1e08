"""End to end: sik_node as a managed node (``lifecycle:=true``) and its ``/diagnostics``.

The transitions are driven over ROS through the standard ``~/change_state`` and ``~/get_state``
services of a real node subprocess, on the tiny test bundle; requests are sent in every state.
"""

import os
from pathlib import Path
import subprocess
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from lifecycle_msgs.msg import State, Transition
from lifecycle_msgs.srv import ChangeState, GetState
import pytest
import rclpy
from rclpy.signals import SignalHandlerOptions

import harness
from sik_interfaces.srv import SolveIK, SolvePath

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(240)]

R = SolveIK.Response
ANSWERED = (R.SUCCESS, R.NO_SOLUTION, R.TIMEOUT)
TARGET = (0.4, -0.2, 0.4)


@pytest.fixture
def graph():
    """An isolated ROS graph and a client node in this process."""
    saved = {k: os.environ.get(k) for k in ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE')}
    env = harness.ros_env()
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('lifecycle_test')
    yield env, node
    node.destroy_node()
    rclpy.shutdown()
    for key, value in saved.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


def start(env, tmp_path: Path, model_dir: str, *params: str) -> subprocess.Popen:
    log = open(tmp_path / 'node.log', 'wb')
    proc = harness.launch_node(model_dir, params=list(params), env=env, stdout=log,
                               stderr=subprocess.STDOUT)
    proc.log_path = tmp_path / 'node.log'
    return proc


def change(node, client, transition: int) -> bool:
    answer = harness.call(node, client, ChangeState.Request(
        transition=Transition(id=transition)), timeout=120.0, attempt=120.0)
    assert answer is not None, 'no answer from ~/change_state'
    return answer.success


def state(node, client) -> int:
    answer = harness.call(node, client, GetState.Request(), timeout=20.0)
    assert answer is not None, 'no answer from ~/get_state'
    return answer.current_state.id


def solve(node, client, timeout: float = 20.0):
    answer = harness.call(node, client, harness.pose_request(TARGET), timeout)
    assert answer is not None, 'no answer'
    return answer


def test_transitions_over_ros(graph, tmp_path, tiny_bundle):
    """Transitions over ROS: requests are refused unless active, never left unanswered.

    unconfigured -> (a failed configure) -> inactive -> active -> inactive -> cleanup ->
    active again -> shutdown (the process exits 0).
    """
    env, node = graph
    later = tmp_path / 'bundle'                # absent at first: the first configure fails
    proc = start(env, tmp_path, str(later), 'lifecycle:=true')
    try:
        change_client = node.create_client(ChangeState, '/sik_node/change_state')
        state_client = node.create_client(GetState, '/sik_node/get_state')
        ik = node.create_client(SolveIK, '/sik_node/solve_ik')
        path = node.create_client(SolvePath, '/sik_node/solve_path')
        assert harness.wait_for_service(node, change_client, proc, 90.0), \
            proc.log_path.read_text()
        assert state(node, state_client) == State.PRIMARY_STATE_UNCONFIGURED
        answer = solve(node, ik)
        assert answer.error_code == R.TIMEOUT and 'unconfigured' in answer.message

        assert not change(node, change_client, Transition.TRANSITION_CONFIGURE)
        assert state(node, state_client) == State.PRIMARY_STATE_UNCONFIGURED
        later.symlink_to(Path(tiny_bundle).resolve(), target_is_directory=True)
        assert change(node, change_client, Transition.TRANSITION_CONFIGURE)
        assert state(node, state_client) == State.PRIMARY_STATE_INACTIVE
        answer = solve(node, ik)
        assert answer.error_code == R.TIMEOUT and 'inactive' in answer.message

        assert change(node, change_client, Transition.TRANSITION_ACTIVATE)
        assert state(node, state_client) == State.PRIMARY_STATE_ACTIVE
        answer = solve(node, ik)
        assert answer.error_code in ANSWERED and 'is active' not in answer.message
        assert answer.solutions, answer.message

        assert change(node, change_client, Transition.TRANSITION_DEACTIVATE)
        request = SolvePath.Request()
        request.waypoints = [harness.pose_request(TARGET).target] * 2
        refused = harness.call(node, path, request, timeout=10.0)
        assert refused is not None and refused.error_code == R.TIMEOUT
        assert 'inactive' in refused.message

        assert change(node, change_client, Transition.TRANSITION_CLEANUP)
        assert state(node, state_client) == State.PRIMARY_STATE_UNCONFIGURED
        assert change(node, change_client, Transition.TRANSITION_CONFIGURE)
        assert change(node, change_client, Transition.TRANSITION_ACTIVATE)
        answer = solve(node, ik)
        assert answer.solutions, answer.message

        assert change(node, change_client, Transition.TRANSITION_ACTIVE_SHUTDOWN)
        assert proc.wait(20) == 0, proc.log_path.read_text()
    finally:
        harness.stop_node(proc)
    log = proc.log_path.read_text()
    assert 'configure failed: cannot load the IK bundle' in log
    assert 'Traceback' not in log


def test_diagnostics(graph, tmp_path, tiny_bundle):
    """/diagnostics: one sik_node status with the bundle, rate, latency, failures by code.

    The same figures are in the node's log at shutdown.
    """
    env, node = graph
    proc = start(env, tmp_path, str(tiny_bundle))
    statuses = []
    node.create_subscription(DiagnosticArray, '/diagnostics',
                             lambda m: statuses.extend(m.status), 10)
    try:
        ik = node.create_client(SolveIK, '/sik_node/solve_ik')
        assert harness.wait_for_service(node, ik, proc, 90.0), proc.log_path.read_text()
        codes = [solve(node, ik).error_code for _ in range(3)]
        bad = harness.pose_request((float('nan'), 0.0, 0.4))
        assert harness.call(node, ik, bad, 10.0).error_code == R.INVALID_GOAL

        def values():
            if not statuses:
                return {}
            return {kv.key: kv.value for kv in statuses[-1].values}
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline and values().get('requests') != '4':
            rclpy.spin_once(node, timeout_sec=0.2)
        status = statuses[-1]
        v = values()
        assert status.name.startswith('sik_node') and v['requests'] == '4', v
        assert status.level == DiagnosticStatus.OK, status.message
        assert v['bundle'] == str(tiny_bundle) and v['state'] == 'active'
        assert v['failures INVALID_GOAL'] == '1'
        assert float(v['requests per second']) > 0
        assert 0 < float(v['latency p50 [ms]']) <= float(v['latency p99 [ms]'])
        assert v['solver processes'].startswith('none (')
        assert v['robot_description'] == 'not given'
        assert 'failures SUCCESS' not in v
        assert codes.count(R.SUCCESS) + sum(
            int(v.get(f'failures {n}', 0)) for n in ('NO_SOLUTION', 'TIMEOUT')) == 3
    finally:
        assert harness.stop_node(proc) == 0
    log = proc.log_path.read_text()
    assert '4 requests (' in log and 'failures: INVALID_GOAL 1' in log, log[-2000:]
