"""SelectiveIK.solve_batch: the answers of solve, in order, from worker processes."""

import numpy as np
import pinocchio as pin
import pytest

from sik_ros.errors import InvalidGoal, InvalidSeed
from sik_ros.solver import parallel, SelectiveIK

pytestmark = pytest.mark.e2e  # starts worker processes


def pose_targets(ik, count, seed=0):
    """Reachable pose targets: FK of random configurations within the limits."""
    q = np.random.default_rng(seed).uniform(ik.robot.lower, ik.robot.upper,
                                            (count, ik.robot.dof))
    pos, quat = zip(*(ik.fk(qi) for qi in q))
    return np.array(pos), np.array(quat)


def exact_by_pinocchio(ik, q, position, quaternion):
    """Whether Pinocchio's FK of ``q`` meets the goal within the solver's tolerances."""
    tip = ik.robot.pin_placement(q)
    goal = pin.Quaternion(quaternion[3], *quaternion[:3]).normalized().matrix()
    angle = np.linalg.norm(pin.log3(goal.T @ tip.rotation))
    return (np.linalg.norm(tip.translation - position) <= ik.config.position_tolerance * 1.01
            and angle <= ik.config.orientation_tolerance * 1.01)


def check_same_as_solve(ik, pos, quat, batch):
    """Each batch answer is solve's for its row, and every exact solution holds by Pinocchio."""
    assert len(batch) == len(pos)
    serial = [ik.solve(p, q, num_solutions=6) for p, q in zip(pos, quat)]
    exact = 0
    for i, (a, b) in enumerate(zip(serial, batch)):
        assert a.success == b.success, i
        assert len(a.solutions) == len(b.solutions), i
        for sa, sb in zip(a.solutions, b.solutions):
            assert np.allclose(sa.q, sb.q, atol=1e-9), i
            assert np.allclose(sa.posture_index, sb.posture_index, atol=1e-5), i
            if sb.position_error <= ik.config.position_tolerance and \
                    sb.orientation_error <= ik.config.orientation_tolerance:
                assert exact_by_pinocchio(ik, sb.q, pos[i], quat[i]), i
                exact += 1
    assert exact >= len(pos)  # at least one exact solution per target on average


def test_batch_on_two_processes_gives_solves_answers_in_order(tiny_bundle):
    """Two forked workers answer 40 pose targets exactly as solve does, in target order."""
    ik = SelectiveIK.load(tiny_bundle)
    pos, quat = pose_targets(ik, 40)
    batch = ik.solve_batch(pos, quat, num_solutions=6, workers=2, progress=True)
    check_same_as_solve(ik, pos, quat, batch)


def test_spawned_workers_load_the_bundle_and_answer_alike(tiny_bundle, monkeypatch):
    """Spawned workers (as in a process running rclpy) load the bundle and answer as solve."""
    monkeypatch.setattr(parallel, '_start_method', lambda ik: 'spawn')
    ik = SelectiveIK.load(tiny_bundle)
    pos, quat = pose_targets(ik, 32, seed=1)
    check_same_as_solve(ik, pos, quat, ik.solve_batch(pos, quat, num_solutions=6, workers=2))


def test_second_arm_batch_answers_as_solve(ur5_bundle):
    """A UR5 (6 joints) batch on two workers is solve's answers, each exact by Pinocchio."""
    ik = SelectiveIK.load(ur5_bundle[0])
    pos, quat = pose_targets(ik, 32, seed=2)
    check_same_as_solve(ik, pos, quat, ik.solve_batch(pos, quat, num_solutions=6, workers=2))


def test_a_bad_row_is_refused_naming_it(tiny_bundle):
    """A NaN target, a zero quaternion or a bad seed row raise solve's error naming the row."""
    ik = SelectiveIK.load(tiny_bundle)
    pos, quat = pose_targets(ik, 5)
    bad = pos.copy()
    bad[3, 1] = np.nan
    with pytest.raises(InvalidGoal, match='target 3: position') as err:
        ik.solve_batch(bad, quat)
    assert err.value.row == 3
    zero = quat.copy()
    zero[1] = 0.0
    with pytest.raises(InvalidGoal, match='target 1: orientation'):
        ik.solve_batch(pos, zero)
    seeds = np.repeat(((ik.robot.lower + ik.robot.upper) / 2)[None], 5, 0)
    seeds[4, 0] = ik.robot.upper[0] + 1.0
    with pytest.raises(InvalidSeed, match='target 4:'):
        ik.solve_batch(pos, quat, seed=seeds)
    with pytest.raises(InvalidGoal):
        ik.solve_batch(pos[:, :2])
