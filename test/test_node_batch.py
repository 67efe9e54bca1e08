"""End to end: ``~/solve_ik_batch`` on a real sik_node with the bundled Panda (docs/interfaces.md).

Two nodes, one after the other (``max_batch_targets`` set to 600): one solving in its executor
threads, one with two solver processes, whose batches run one lane per process and one more.
Every solution is checked by
Pinocchio's FK of the returned joint values (``Robot.pin_placement``), not by the errors the node
reports.
"""

import threading
import time

import numpy as np
import pinocchio as pin
import pytest
import rclpy

import harness
from sik_interfaces.srv import SolveIK, SolveIKBatch
from sik_ros.kinematics.robots import load_robot
from sik_ros.ros.batch_service import GiveWay
from sik_ros.ros.client import batch_request

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(120)]

R = SolveIKBatch.Response
BASE = 'panda_link0'
POS_TOL, ROT_TOL = 1e-4, 1e-3        # config/panda.yaml
CAP = 600
#: One try of a batch call waits this long before it resends the request [s].
ATTEMPT = 60.0


@pytest.fixture(scope='module')
def robot():
    """The Panda (7 joints, panda_link0 -> panda_hand_tcp)."""
    return load_robot('panda')


@pytest.fixture(scope='module', params=[0, 2], ids=['threads', 'processes'])
def ros(tmp_path_factory, request):
    """A sik_node with the bundled Panda and a client node with both services, once up.

    The node has ``request.param`` solver processes.
    """
    with harness.node_with_clients(
            tmp_path_factory, 'batch_user',
            {'batch': (SolveIKBatch, '/sik_node/solve_ik_batch'),
             'single': (SolveIK, '/sik_node/solve_ik')},
            [f'max_batch_targets:={CAP}', f'solver_processes:={request.param}']) as node:
        yield node


def goals(robot, count, seed):
    """Reachable pose goals: positions (N, 3) [m], quaternions (N, 4) of random configurations."""
    q = np.random.default_rng(seed).uniform(robot.lower, robot.upper, (count, robot.dof))
    return robot.fk_batch(q)


def batch(node, request, timeout=60.0):
    """The answer to a batch; fails the test when none comes."""
    answer = harness.call(node, node.batch, request, timeout=timeout, attempt=ATTEMPT)
    assert answer is not None, 'no answer'
    return answer


def check_exact(robot, result, position, quaternion):
    """A target's result: SUCCESS, at least one solution, every one exact by Pinocchio's FK."""
    assert result.error_code == R.SUCCESS, result.message
    assert len(result.solutions) >= 1 and result.num_families >= 1, result.message
    goal = pin.Quaternion(*np.roll(quaternion, 1)).normalized().matrix()  # w x y z
    for s in result.solutions:
        assert list(s.joint_state.name) == robot.joint_names
        assert s.joint_state.header.frame_id == BASE
        placement = robot.pin_placement(np.array(s.joint_state.position))
        assert np.linalg.norm(placement.translation - position) <= POS_TOL
        assert np.linalg.norm(pin.log3(goal.T @ placement.rotation)) <= ROT_TOL + 1e-9


def test_reachable_poses_all_exact(ros, robot):
    """50 random reachable pose goals in one batch: every one SUCCESS, every solution exact."""
    p, quat = goals(robot, 50, seed=11)
    request = batch_request(p, quat, max_solutions=4)
    request.timeout.sec = 1  # per target: the machine may be busy; what is tested is exactness
    answer = batch(ros, request)
    assert answer.error_code == R.SUCCESS, answer.message
    assert len(answer.results) == 50 and '50 targets: 50 SUCCESS' in answer.message
    for i, result in enumerate(answer.results):
        check_exact(robot, result, p[i], quat[i])


def test_bad_rows_get_their_codes(ros, robot):
    """NaN, a zero quaternion and an unknown frame are coded in their rows; the others solved."""
    p, quat = goals(robot, 6, seed=12)
    request = batch_request(p, quat, max_solutions=4)
    request.timeout.sec = 1
    request.targets[1].pose.position.x = float('nan')
    o = request.targets[3].pose.orientation
    o.x = o.y = o.z = o.w = 0.0
    request.targets[4].header.frame_id = 'world'
    answer = batch(ros, request)
    assert answer.error_code == R.SUCCESS, answer.message
    codes = [r.error_code for r in answer.results]
    assert codes == [R.SUCCESS, R.INVALID_GOAL, R.SUCCESS, R.INVALID_GOAL, R.INVALID_FRAME,
                     R.SUCCESS], [r.message for r in answer.results]
    for i in (1, 3, 4):
        bad = answer.results[i]
        assert bad.message.startswith(f'target {i}: ') and not bad.solutions, bad.message
        assert bad.num_families == 0
    assert "'world'" in answer.results[4].message
    for i in (0, 2, 5):
        check_exact(robot, answer.results[i], p[i], quat[i])


def test_whole_request_problems_are_the_response_code(ros, robot):
    """Over the cap, no targets, a bad seed or bad obstacles: the response's code, no results."""
    p, quat = goals(robot, CAP + 1, seed=13)
    cases = []
    over = batch_request(p, quat)
    cases.append((over, R.INVALID_GOAL, f'{CAP + 1} targets; at most {CAP}'))
    cases.append((batch_request(p[:0]), R.INVALID_GOAL, 'no targets'))
    outside = batch_request(p[:3], quat[:3])
    outside.seed.name = list(robot.joint_names)
    outside.seed.position = [float(robot.upper[0]) + 0.5] + [0.0] * (robot.dof - 1)
    cases.append((outside, R.INVALID_SEED, 'panda_joint1'))
    unknown = batch_request(p[:3], quat[:3])
    unknown.seed.name, unknown.seed.position = ['elbow'], [0.0]
    cases.append((unknown, R.INVALID_SEED, 'unknown joints'))
    obstacles = batch_request(p[:3], quat[:3])
    obstacles.obstacle_poses = [obstacles.targets[0].pose]
    cases.append((obstacles, R.INVALID_GOAL, '0 obstacles but 1 obstacle_poses'))
    for request, code, words in cases:
        answer = batch(ros, request)
        assert answer.error_code == code and words in answer.message, answer.message
        assert not answer.results


def test_solve_ik_answers_during_a_large_batch(ros, robot):
    """~/solve_ik calls made while a 600-target batch is solved are answered, exact, meanwhile."""
    p, quat = goals(robot, CAP, seed=14)
    batch(ros, batch_request(p[:1], quat[:1]))  # a reply Fast DDS drops is resent here
    big = batch_request(p, quat, max_solutions=16)
    big.timeout.nanosec = 200_000_000
    future = ros.batch.call_async(big)
    done = threading.Event()
    future.add_done_callback(lambda _: done.set())
    time.sleep(0.1)  # the batch is under way
    sp, squat = goals(robot, 5, seed=15)
    during, seconds = [], []
    for i in range(5):
        single = harness.pose_request(sp[i], squat[i], max_solutions=4)
        single.timeout.sec = 1
        t0 = time.monotonic()
        answer = harness.call(ros, ros.single, single, timeout=20.0)
        seconds.append(time.monotonic() - t0)
        assert answer is not None, 'no answer to ~/solve_ik during the batch'
        during.append(not done.is_set())
        check_exact(robot, answer, sp[i], squat[i])
    rclpy.spin_until_future_complete(ros, future, timeout_sec=90.0)
    print(f'~/solve_ik round trips during the batch: {[round(s * 1e3, 1) for s in seconds]} ms')
    assert future.done(), 'no answer to the batch'
    answer = future.result()
    assert all(during), f'the batch ended before the calls were answered ({answer.message})'
    assert answer.error_code == R.SUCCESS and len(answer.results) == CAP, answer.message
    assert all(r.error_code in (R.SUCCESS, R.NO_SOLUTION, R.TIMEOUT) for r in answer.results)
    ok = [i for i, r in enumerate(answer.results) if r.error_code == R.SUCCESS]
    assert len(ok) >= 0.95 * CAP, answer.message
    for i in ok:
        check_exact(robot, answer.results[i], p[i], quat[i])


def test_a_batch_gives_way_to_other_requests():
    """Between targets a batch waits while another request is in flight, until it is answered.

    (No node: :class:`GiveWay` over a counter standing in for the guard's.)
    """
    in_flight = [1]  # the batch itself
    way = GiveWay(lambda: in_flight[0])
    with way.batch():
        assert way.others() == 0 and way.wait(5.0) == 0.0
        in_flight[0] = 2  # another request comes
        assert 0.05 <= way.wait(0.05) < 1.0, 'waits for its limit at most'

        def answer():
            time.sleep(0.1)
            in_flight[0] = 1
            way.answered('solve_ik', R.SUCCESS, 0.1)

        threading.Thread(target=answer).start()
        t0 = time.monotonic()
        waited = way.wait(5.0)
        assert 0.09 <= waited <= time.monotonic() - t0 < 2.0, 'woken by the answer'
        in_flight[0] = 2
        with way.batch():  # a second batch does not count as another request
            in_flight[0] = 3
            assert way.others() == 1


def test_lanes_keep_target_order_and_raise_what_they_meet():
    """Lanes answering out of turn give the results in target order, refusals, errors raised.

    Three lanes; a refusal met mid-batch answers the targets not yet taken; an unexpected error
    is re-raised.

    (No node: :class:`_BatchRun` with answers that sleep at random and a counter of requests.)
    """
    from types import SimpleNamespace

    from sik_ros.ros.batch_service import _BatchRun, lanes, result_msg

    assert lanes(0) == 1 and lanes(1) == 2 and lanes(2) == 3
    rng = np.random.default_rng(0)
    delays = rng.uniform(0, 0.004, 60)
    request = SimpleNamespace(targets=list(range(60)))
    way = GiveWay(lambda: 1)

    def answer(i, target):
        time.sleep(delays[i])
        return result_msg(R.SUCCESS, f'{i}:{target}')

    run = _BatchRun(request, 60, lambda: None, way, 0.05, answer)
    run.solve(3)
    assert [r.message for r in run.results] == [f'{i}:{i}' for i in range(60)]

    taken = []

    def refusal():
        return (R.NO_ROBOT, 'the arm is no longer served') if len(taken) >= 20 else None

    def counted(i, target):
        taken.append(i)
        return answer(i, target)

    run = _BatchRun(request, 60, refusal, way, 0.05, counted)
    run.solve(3)
    codes = [r.error_code for r in run.results]
    assert len(codes) == 60 and codes.count(R.SUCCESS) == len(taken) >= 20
    refused = [r.message for r in run.results if r.error_code != R.SUCCESS]
    assert set(refused) == {'the arm is no longer served'}

    def broken(i, target):
        if i == 7:
            raise RuntimeError('lane failure')
        return answer(i, target)

    with pytest.raises(RuntimeError, match='lane failure'):
        _BatchRun(request, 60, lambda: None, way, 0.05, broken).solve(3)
