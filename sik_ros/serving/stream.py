"""A goal stream served like a servo: newest goal wins, continuity, bounded commands (no ROS).

A teleoperation device, a visual servo or a jogging tool publishes goals at 100-1000 Hz and
follows the answers: only the newest goal matters. :class:`LatestGoal` is the one-slot mailbox
between the subscription and the thread that solves: a goal that arrives while another waits
replaces it (counted, never answered), so answers leave in the order of their goals and none
follows the answer to a newer goal. :class:`ServoState` keeps what consecutive answers share:
the seed (the previous answer, or the arm's measured state where that is newer), the joint step
that counts as a jump, and the last command, whose next step :func:`limit_step` bounds by the
joint velocity limits times the goal period.
"""

from dataclasses import dataclass
import threading
import time
from typing import Generic, Optional, Tuple, TypeVar

import numpy as np

T = TypeVar('T')
#: The longest goal period a command step is bounded by [s]: after a pause in the stream (or
#: for its first goal) the arm is not allowed to travel as if the pause had been one period.
MAX_COMMAND_PERIOD = 0.1
#: A goal this long after the previous answer starts a new stream [s]: the previous answer is
#: no longer its seed, nor what a jump is judged against (the measured state still is).
NEW_STREAM_GAP = 0.5


class LatestGoal(Generic[T]):
    """A one-slot mailbox, safe from every thread: a new goal replaces the one waiting."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._item: Optional[T] = None
        self._closed = False
        self._replaced_since = 0
        #: goals put since start
        self.received = 0
        #: goals replaced by a newer one before they were taken (never answered)
        self.replaced = 0

    def put(self, item: T, skipped: int = 0) -> None:
        """Hand over the newest goal; one still waiting is replaced and counted.

        Args:
            item: the newest goal.
            skipped: older goals received with it and never handed over (counted as
                received and replaced).
        """
        with self._cond:
            self.received += 1 + skipped
            dropped = skipped + (self._item is not None)
            self.replaced += dropped
            self._replaced_since += dropped
            self._item = item
            self._cond.notify()

    def take(self, timeout: float) -> Optional[Tuple[T, int]]:
        """The newest goal and how many were replaced since the last take; None on timeout.

        Args:
            timeout: the longest wait [s].
        """
        with self._cond:
            if self._item is None and not self._closed:
                self._cond.wait(timeout)
            if self._item is None:
                return None
            item, replaced = self._item, self._replaced_since
            self._item, self._replaced_since = None, 0
            return item, replaced

    def close(self) -> None:
        """Wake a waiting :meth:`take` (the server is stopping)."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()


def max_joint_step(q_from: np.ndarray, q_to: np.ndarray) -> float:
    """The largest joint change between two configurations [rad or m]."""
    return float(np.max(np.abs(np.asarray(q_to, float) - np.asarray(q_from, float))))


def limit_step(q_from: np.ndarray, q_to: np.ndarray, max_step: np.ndarray) -> np.ndarray:
    """``q_to``, or the point on the way to it where no joint moves more than ``max_step``.

    The step is scaled as a whole (its direction is kept), so the arm moves along the line
    towards the answer.

    Args:
        q_from: the last commanded configuration.
        q_to: the answer.
        max_step: per joint, the largest change allowed (velocity limit times period).
    """
    q_from, q_to = np.asarray(q_from, float), np.asarray(q_to, float)
    step = q_to - q_from
    with np.errstate(divide='ignore', invalid='ignore'):
        ratio = np.where(np.abs(step) > 0, np.abs(step) / np.asarray(max_step, float), 0.0)
    worst = float(np.max(ratio)) if len(ratio) else 0.0
    return q_to.copy() if worst <= 1.0 else q_from + step / worst


@dataclass
class _Stamped:
    q: np.ndarray
    at: float  # time.monotonic() [s]


class ServoState:
    """What consecutive answers of one stream share; used by the one thread that solves."""

    def __init__(self, velocity_limits: np.ndarray,
                 clock=time.monotonic) -> None:
        """Start a stream with no answer, no measured state and no command.

        Args:
            velocity_limits: per joint [rad/s or m/s] (bounds each command step).
            clock: the clock of goal stamps and arrivals [s] (the node's ROS clock).
        """
        self.velocity_limits = np.asarray(velocity_limits, float)
        self._clock = clock
        self._answer: Optional[_Stamped] = None
        self._state: Optional[_Stamped] = None
        self._command: Optional[np.ndarray] = None
        self._command_stamp: Optional[float] = None
        #: answers that would have jumped (not followed, not commanded)
        self.jumps = 0

    def measured(self, q: Optional[np.ndarray], at: Optional[float] = None) -> None:
        """The arm's measured state (``joint_states``), received at ``at`` (default: now).

        None forgets it.
        """
        when = self._clock() if at is None else at
        self._state = None if q is None else _Stamped(np.asarray(q, float), when)

    @property
    def measured_at(self) -> float:
        """When the measured state in use was received (-inf: none) [s]."""
        state = self._state
        return -float('inf') if state is None else state.at

    def seed(self) -> Optional[np.ndarray]:
        """The previous answer, or the measured state where that is newer; None for neither.

        An answer older than :data:`NEW_STREAM_GAP` belongs to an earlier stream: not a seed.
        """
        answer, state = self._answer, self._state
        if answer is not None and self._clock() - answer.at > NEW_STREAM_GAP:
            answer = None
        if answer is None:
            return None if state is None else state.q
        if state is None or state.at <= answer.at:
            return answer.q
        return state.q

    def follow(self, q: np.ndarray) -> None:
        """The answer just given: the next goal is seeded by it and judged against it."""
        self._answer = _Stamped(np.asarray(q, float), self._clock())

    def command(self, q: np.ndarray, goal_stamp: float) -> Optional[np.ndarray]:
        """The next command towards answer ``q``, bounded by the velocity limits; None if none.

        The step from the last command (or, for the first, from the measured state) is at most
        the joint velocity limits times the goal period: the time between this goal's stamp and
        the last commanded goal's, at most :data:`MAX_COMMAND_PERIOD`. With neither a command
        nor a measured state to start from there is no command: a step from an unknown state
        cannot be bounded.

        Args:
            q: the answer.
            goal_stamp: the goal's header stamp [s].
        """
        start = self._command
        if start is None:
            state = self._state
            if state is None:
                return None
            start = state.q
        period = self.period(goal_stamp)
        out = limit_step(start, q, self.velocity_limits * period)
        self._command, self._command_stamp = out, goal_stamp
        return out

    def period(self, goal_stamp: float) -> float:
        """The goal period a command step is bounded by [s]: since the last command's goal."""
        last = self._command_stamp
        if last is None or not goal_stamp > last:
            return MAX_COMMAND_PERIOD
        return min(goal_stamp - last, MAX_COMMAND_PERIOD)
