"""Faults against a real sik_node: bad start-ups, hostile requests, shutdown under load."""

import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from rclpy.executors import SingleThreadedExecutor
from shape_msgs.msg import SolidPrimitive

import harness
from sik_interfaces.srv import SolveIK

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(240)]
R = SolveIK.Response


@pytest.mark.parametrize('args, words', [
    (['--params-file', '/nonexistent/params.yaml'], 'params file'),
    (['-p'], 'trailing -p'),
    (['-p', 'timeout:=-1.0'], 'timeout'),
])
def test_bad_start_ups_are_one_fatal_line(graph, args, words):
    """A missing params file, a trailing -p, a bad value: exit 1 with one FATAL line."""
    env, _ = graph
    run = subprocess.run([sys.executable, '-m', 'sik_ros.ros.run', '--ros-args', *args],
                         env=env, capture_output=True, text=True, timeout=120)
    out = run.stdout + run.stderr
    fatal = [line for line in out.splitlines() if 'FATAL' in line]
    assert run.returncode == 1 and len(fatal) == 1 and words in fatal[0], out
    assert 'Traceback' not in out


def test_help_lists_the_parameters_and_starts_nothing(graph):
    """``sik_node --help``: the usage and every parameter, exit 0, no node started."""
    env, _ = graph
    run = subprocess.run([sys.executable, '-m', 'sik_ros.ros.run', '--help'], env=env,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and run.stdout.startswith('usage: sik_node'), run.stderr
    from sik_ros.ros.params import SPECS
    assert all(f'  {spec.name} (' in run.stdout for spec in SPECS)
    assert 'ready' not in run.stdout + run.stderr


def test_an_unknown_argument_is_one_line_and_exit_2(graph):
    """An argument outside ``--ros-args``: one line naming it, exit 2, no traceback."""
    env, _ = graph
    run = subprocess.run([sys.executable, '-m', 'sik_ros.ros.run', '--bundle', 'x',
                          '--ros-args', '-p', 'timeout:=1.0'], env=env, capture_output=True,
                         text=True, timeout=120)
    lines = run.stderr.strip().splitlines()
    assert run.returncode == 2 and len(lines) == 1 and "'--bundle'" in lines[0], run.stderr
    assert run.stdout == ''


def _box_request(position, count, timeout):
    req = harness.pose_request(position, None, 16)
    rng = np.random.default_rng(0)
    for _ in range(count):
        box = SolidPrimitive(type=SolidPrimitive.BOX, dimensions=[0.05, 0.05, 0.05])
        req.obstacles.append(box)
        pose = harness.pose_request(tuple(rng.uniform(-1.5, 1.5, 3))).target.pose
        req.obstacle_poses.append(pose)
    req.timeout.sec, req.timeout.nanosec = int(timeout), int((timeout % 1) * 1e9)
    return req


def test_hostile_requests_get_codes_in_time_and_shutdown_under_load_is_clean(
        tiny_bundle, graph, tmp_path):
    """Huge values, too many obstacles, a tight deadline get codes; SIGTERM under load exits 0.

    The 10 ms request ends in SUCCESS or in a TIMEOUT that names its 10 ms deadline.
    """
    env, node = graph
    log_path = tmp_path / 'node.log'
    with open(log_path, 'wb') as log:
        proc = harness.launch_node(str(tiny_bundle), env=env, stdout=log, stderr=subprocess.STDOUT)
    client = node.create_client(SolveIK, '/sik_node/solve_ik')
    try:
        assert harness.wait_for_service(node, client, proc, 90.0), log_path.read_text()
        huge = harness.call(node, client, harness.pose_request((1e300, 0.0, 0.4)), 20.0)
        assert huge.error_code == R.INVALID_GOAL and '100 m' in huge.message, huge.message
        quat = harness.call(node, client, harness.pose_request((0.4, 0.0, 0.4),
                                                               (1e200, 0, 0, 1e200)), 20.0)
        assert quat.error_code in (R.SUCCESS, R.NO_SOLUTION), quat.message
        many = harness.call(node, client, _box_request((0.4, 0.0, 0.4), 2000, 0.05), 20.0)
        assert many.error_code == R.INVALID_GOAL and 'at most 256' in many.message
        tight = harness.call(node, client, _box_request((0.4, 0.0, 0.4), 256, 0.01), 20.0)
        assert tight.error_code == R.SUCCESS or (
            tight.error_code == R.TIMEOUT and 'timed out after 10 ms' in tight.message), \
            tight.message
        # load from several threads, then SIGTERM in the middle of it
        answers, stop = [], threading.Event()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        spinner = threading.Thread(target=executor.spin, daemon=True)
        spinner.start()

        def load():
            while not stop.is_set():
                future = client.call_async(_box_request((0.4, 0.1, 0.4), 64, 2.0))
                deadline = time.monotonic() + 5.0
                while not future.done() and time.monotonic() < deadline:
                    time.sleep(0.005)
                if future.done():
                    answers.append(future.result().error_code)
        threads = [threading.Thread(target=load, daemon=True) for _ in range(4)]
        for t in threads:
            t.start()
        time.sleep(2.0)
        proc.terminate()
        code = proc.wait(30.0)  # a hang guard (TimeoutExpired), not a speed claim
        stop.set()
        executor.shutdown(timeout_sec=1.0)
        assert code == 0, (code, log_path.read_text()[-3000:])
        assert answers and set(answers) <= {R.SUCCESS, R.TIMEOUT, R.NO_SOLUTION}, answers
        log = log_path.read_text()
        assert 'Traceback' not in log and 'InvalidHandle' not in log, log[-3000:]
    finally:
        node.destroy_client(client)
        harness.stop_node(proc)


def _rss_mb(pid):
    with open(f'/proc/{pid}/status') as f:
        return next(int(line.split()[1]) for line in f if line.startswith('VmRSS:')) / 1024


def test_parameter_churn_does_not_grow_the_solver_process(tiny_bundle, graph, tmp_path):
    """40 distinct position_tolerance values, a request each: the solver process stays flat."""
    import os
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters
    env, node = graph
    with open(tmp_path / 'node.log', 'wb') as log:
        proc = harness.launch_node(str(tiny_bundle), ['solver_processes:=1'], env=env, stdout=log,
                                   stderr=subprocess.STDOUT)
    client = node.create_client(SolveIK, '/sik_node/solve_ik')
    params = node.create_client(SetParameters, '/sik_node/set_parameters')
    try:
        assert harness.wait_for_service(node, client, proc, 90.0)
        assert params.wait_for_service(timeout_sec=10.0)
        with open(f'/proc/{proc.pid}/task/{proc.pid}/children') as f:
            child = [int(c) for c in f.read().split()
                     if 'multiprocessing' in open(f'/proc/{c}/cmdline').read()][0]

        def churn(k):
            value = ParameterValue(type=ParameterType.PARAMETER_DOUBLE,
                                   double_value=1e-4 * (1 + k / 1000))
            harness.call(node, params, SetParameters.Request(
                parameters=[Parameter(name='position_tolerance', value=value)]), 10.0)
            request = harness.pose_request((0.4, 0.1, 0.4), None, 4)
            answer = harness.call(node, client, request, 20.0)
            assert answer.error_code in (R.SUCCESS, R.NO_SOLUTION), answer.message
        for k in range(8):  # warm-up: the cache fills to its bound
            churn(k)
        before = _rss_mb(child)
        for k in range(8, 48):
            churn(k)
        grown = _rss_mb(child) - before
        assert grown < 15.0, f'{grown:.1f} MB after 40 new settings'
        assert os.path.exists(f'/proc/{child}')  # the same process all along
    finally:
        node.destroy_client(client)
        node.destroy_client(params)
        harness.stop_node(proc)


def _solver_children(pid):
    """Process ids of a node's solver processes (multiprocessing spawn children).

    Every thread's children: replacements are started from the pool's restart threads.
    """
    import glob
    out, children = [], []
    for path in glob.glob(f'/proc/{pid}/task/*/children'):
        try:
            with open(path) as f:
                children += f.read().split()
        except OSError:
            pass
    for c in children:
        try:
            with open(f'/proc/{c}/cmdline') as f:
                if 'spawn_main' in f.read():
                    out.append(int(c))
        except OSError:
            pass
    return out


def test_solver_pool_heals_while_requests_fall_back(tiny_bundle, graph, tmp_path):
    """Kill every solver process as it starts: solves still succeed, then the pool heals."""
    import os
    import signal
    env, node = graph
    log_path = tmp_path / 'node.log'
    with open(log_path, 'wb') as log:
        proc = harness.launch_node(str(tiny_bundle), ['solver_processes:=2'], env=env,
                                   stdout=log, stderr=subprocess.STDOUT)
    client = node.create_client(SolveIK, '/sik_node/solve_ik')
    try:
        assert harness.wait_for_service(node, client, proc, 120.0), log_path.read_text()
        stop = threading.Event()
        killed = []

        def killer():
            while not stop.is_set():
                for c in _solver_children(proc.pid):
                    try:
                        os.kill(c, signal.SIGKILL)
                        killed.append(c)
                    except ProcessLookupError:
                        pass
                time.sleep(0.02)
        thread = threading.Thread(target=killer, daemon=True)
        thread.start()
        codes = []
        # 3 s of kills: the pool's first four tries to restart (0.25, 0.5, 1 and 2 s apart) fail
        # meanwhile, and its fifth comes about 4 s after the first kill, the kills over (after
        # 8 s of kills, its next try came 8 s later)
        t_end = time.monotonic() + 3.0
        while time.monotonic() < t_end:
            request = harness.pose_request((0.4, 0.1, 0.4), None, 4)
            request.timeout.sec = 2
            answer = harness.call(node, client, request, 10.0)
            codes.append(None if answer is None else answer.error_code)
        stop.set()
        thread.join()
        assert len(set(killed)) >= 4, killed  # the first two and replacements as they started
        assert codes and set(codes) <= {R.SUCCESS, R.NO_SOLUTION}, codes
        # the pool heals: both processes back, serving
        deadline = time.monotonic() + 90.0
        while time.monotonic() < deadline and log_path.read_text().count('restarted') < 2:
            time.sleep(0.5)
        log = log_path.read_text()
        assert 'lost' in log and 'failed to start' in log and 'restarted' in log, log[-3000:]
        assert 'Traceback' not in log
        alive = _solver_children(proc.pid)
        assert len(alive) == 2, (alive, log[-2000:])
        answer = harness.call(node, client, harness.pose_request((0.4, 0.1, 0.4), None, 4), 20.0)
        assert answer.error_code in (R.SUCCESS, R.NO_SOLUTION), answer.message
    finally:
        node.destroy_client(client)
        harness.stop_node(proc)
