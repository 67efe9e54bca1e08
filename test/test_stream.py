"""The goal stream's library parts: newest goal wins, the servo's seed, bounded commands."""

import threading

import numpy as np
import pytest

from sik_ros.serving.stream import (LatestGoal, limit_step, MAX_COMMAND_PERIOD, max_joint_step,
                                    NEW_STREAM_GAP, ServoState)


class Clock:
    """A settable monotonic clock [s]."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_newest_goal_replaces_the_waiting_one():
    """Goals put while one waits replace it; the take says how many were replaced."""
    box = LatestGoal()
    for goal in ('a', 'b', 'c'):
        box.put(goal)
    assert box.take(0.0) == ('c', 2)
    assert box.take(0.0) is None
    box.put('d', skipped=5)
    assert box.take(0.0) == ('d', 5)
    assert (box.received, box.replaced) == (9, 7)


def test_take_waits_for_a_goal_from_another_thread():
    """A waiting take returns the goal another thread puts, and close wakes it."""
    box = LatestGoal()
    timer = threading.Timer(0.05, box.put, args=('g',))
    timer.start()
    assert box.take(5.0) == ('g', 0)
    closer = threading.Timer(0.05, box.close)
    closer.start()
    assert box.take(5.0) is None
    timer.join()
    closer.join()


def test_limit_step_bounds_every_joint_and_keeps_the_direction():
    """No joint moves more than its bound; the step points at the answer."""
    rng = np.random.default_rng(0)
    checked = 0
    for _ in range(200):
        start, goal = rng.uniform(-2, 2, 7), rng.uniform(-2, 2, 7)
        bound = rng.uniform(0.01, 0.5, 7)
        out = limit_step(start, goal, bound)
        assert np.all(np.abs(out - start) <= bound + 1e-12)
        step, full = out - start, goal - start
        assert np.allclose(np.cross(step[:3], full[:3]), 0, atol=1e-9)
        assert np.dot(step, full) > 0
        checked += 1
    assert checked == 200
    near = np.full(6, 0.1)
    assert np.array_equal(limit_step(np.zeros(6), near, np.full(6, 0.2)), near)


def test_servo_seed_is_the_newer_of_answer_and_measured_state():
    """The seed is the previous answer unless joint_states arrived after it."""
    clock = Clock()
    servo = ServoState(np.ones(3), clock=clock)
    assert servo.seed() is None
    servo.measured(np.full(3, 1.0))
    assert np.array_equal(servo.seed(), np.full(3, 1.0))
    clock.now = 1.0
    servo.follow(np.full(3, 2.0))
    assert np.array_equal(servo.seed(), np.full(3, 2.0))
    servo.measured(np.full(3, 3.0), at=0.5)   # older than the answer
    assert np.array_equal(servo.seed(), np.full(3, 2.0))
    servo.measured(np.full(3, 4.0), at=1.5)
    assert np.array_equal(servo.seed(), np.full(3, 4.0))
    assert servo.measured_at == 1.5


def test_a_pause_starts_a_new_stream():
    """After NEW_STREAM_GAP without answers the previous answer is no seed; joint_states is."""
    clock = Clock()
    servo = ServoState(np.ones(2), clock=clock)
    servo.follow(np.full(2, 2.0))
    clock.now = NEW_STREAM_GAP * 0.9
    assert np.array_equal(servo.seed(), np.full(2, 2.0))
    clock.now = NEW_STREAM_GAP * 1.1
    assert servo.seed() is None
    servo.measured(np.full(2, -1.0), at=0.0)
    assert np.array_equal(servo.seed(), np.full(2, -1.0))


def test_servo_commands_only_bounded_steps():
    """Commands start from the measured state and move at most velocity x goal period."""
    velocity = np.array([1.0, 2.0, 0.5])
    servo = ServoState(velocity)
    assert servo.command(np.ones(3), goal_stamp=10.0) is None, 'no state to start from'
    servo.measured(np.zeros(3))
    first = servo.command(np.ones(3), goal_stamp=10.0)
    assert np.all(np.abs(first) <= velocity * MAX_COMMAND_PERIOD + 1e-12)
    period = 0.002
    last, sent = first, 0
    for k in range(1, 50):
        out = servo.command(np.full(3, 5.0), goal_stamp=10.0 + k * period)
        assert np.all(np.abs(out - last) <= velocity * period + 1e-12)
        last, sent = out, sent + 1
    assert sent == 49
    assert servo.period(10.0 + 49 * period + 5.0) == MAX_COMMAND_PERIOD
    assert servo.period(0.0) == MAX_COMMAND_PERIOD, 'a stamp going back in time'


@pytest.mark.parametrize('a, b, expected', [((0, 0), (0.1, -0.3), 0.3), ((1, 2), (1, 2), 0.0)])
def test_max_joint_step(a, b, expected):
    """The largest joint change, whichever its sign."""
    assert max_joint_step(np.array(a, float), np.array(b, float)) == pytest.approx(expected)
