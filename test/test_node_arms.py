"""End to end: sik_node serves any bundle with ``-p model_dir:=DIR``, checked against a URDF.

The tiny UR5 bundle that ``sik-build`` makes (conftest's ``ur5_bundle``) is served over DDS;
a ``robot_description`` (parameter or latched topic) whose chain differs from it is refused.
"""

from pathlib import Path
import subprocess
import sys
import time

import numpy as np
import pytest
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

import harness
from sik_interfaces.srv import SolveIK

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(180)]
R = SolveIK.Response


def start(bundle, env, log, *params, params_file=None):
    """``sik_node`` with only ``model_dir`` (and ``params``) set: no Panda parameter file."""
    cmd = [sys.executable, '-m', 'sik_ros.ros.run', '--ros-args']
    if params_file:
        cmd += ['--params-file', str(params_file)]
    for item in (f'model_dir:={bundle}',) + params:
        cmd += ['-p', item]
    return subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT)


def test_any_bundle_is_served_by_model_dir_alone(ur5_bundle, ur5, graph, tmp_path):
    """A UR5 bundle, model_dir only: exact answers in its base frame, other frames refused."""
    env, node = graph
    bundle, _ = ur5_bundle
    with open(tmp_path / 'node.log', 'wb') as log:
        proc = start(bundle, env, log)
    try:
        client = node.create_client(SolveIK, '/sik_node/solve_ik')
        assert harness.wait_for_service(node, client, proc, 90.0), \
            (tmp_path / 'node.log').read_text()
        q = np.random.default_rng(3).uniform(ur5.lower, ur5.upper)
        p, quat = ur5.fk(q)
        answer = harness.call(node, client, harness.pose_request(p, quat, 8, 'base_link'), 20.0)
        assert answer.error_code == R.SUCCESS, answer.message
        assert list(answer.solutions[0].joint_state.name) == ur5.joint_names
        for s in answer.solutions:
            reached, _ = ur5.fk(np.array(s.joint_state.position))
            assert np.linalg.norm(reached - p) <= 1e-4
        wrong = harness.call(node, client, harness.pose_request(p, quat, 8, 'panda_link0'), 20.0)
        assert wrong.error_code == R.INVALID_FRAME and 'base_link' in wrong.message
    finally:
        harness.stop_node(proc)


def test_a_robot_description_that_differs_is_refused(ur5_bundle, ur5, graph, tmp_path):
    """Parameter: the node does not start, one line says what differs. Topic: requests refused."""
    env, node = graph
    bundle, _ = ur5_bundle
    text = Path(ur5.urdf_path).read_text()
    moved = text.replace('xyz="0.0 0.0 0.089159"', 'xyz="0.0 0.0 0.1"', 1)
    params = tmp_path / 'params.yaml'
    params.write_text('/**:\n  ros__parameters:\n    robot_description: |\n'
                      + ''.join(f'      {line}\n' for line in moved.splitlines()))
    with open(tmp_path / 'bad.log', 'wb') as log:
        proc = start(bundle, env, log, params_file=params)
    assert proc.wait(120) == 1
    out = (tmp_path / 'bad.log').read_text()
    assert "joint placements differ at ['shoulder_pan_joint']" in out, out

    with open(tmp_path / 'node.log', 'wb') as log:
        proc = start(bundle, env, log)
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                         reliability=ReliabilityPolicy.RELIABLE)
    pub = node.create_publisher(String, 'robot_description', latched)
    try:
        client = node.create_client(SolveIK, '/sik_node/solve_ik')
        assert harness.wait_for_service(node, client, proc, 90.0), \
            (tmp_path / 'node.log').read_text()
        p, quat = ur5.fk(np.zeros(6))
        pub.publish(String(data=text))  # the same chain: served, once the node has it
        log = tmp_path / 'node.log'
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and \
                "robot_description matches the bundle's chain" not in log.read_text():
            time.sleep(0.2)
        assert "robot_description matches the bundle's chain" in log.read_text(), \
            'the description never arrived'
        ok = harness.call(node, client, harness.pose_request(p, None, 4), 20.0)
        assert ok.error_code == R.SUCCESS, ok.message
        pub.publish(String(data=moved))
        deadline = time.monotonic() + 10
        answer = ok
        while time.monotonic() < deadline and answer.error_code != R.ROBOT_MISMATCH:
            time.sleep(0.2)
            answer = harness.call(node, client, harness.pose_request(p, None, 4), 20.0)
        assert answer.error_code == R.ROBOT_MISMATCH, answer.message
        assert 'shoulder_pan_joint' in answer.message and not answer.solutions
    finally:
        node.destroy_publisher(pub)
        harness.stop_node(proc)
