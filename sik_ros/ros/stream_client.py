"""A client that streams pose goals to ``~/goal`` at a fixed rate and measures the answers.

What a teleoperation device or a visual servo does, measured on the wire: goals along a smooth
circle are published at ``rate`` Hz, each stamped with its own send time (so an answer, which
carries its goal's header, names its goal); an optional simulated arm follows the first solution
of each successful answer and publishes it on ``joint_states``. :func:`stream_report` turns what
came back into figures: goals answered, latency of a goal's own answer, staleness (from each
goal until an answer to it or to a newer goal arrived), answers out of order, answers that
carry a goal's stamp, codes, posture flips and solutions checked by forward kinematics. Used by
``bench/stream.py`` and the end-to-end tests::

    with GoalStreamClient(joint_names, follow=True) as client:   # after rclpy.init()
        client.wait_for_node(10.0)
        record = client.run(circle_goals(centre, 0.1, 500, 10.0), rate=500)
"""

from dataclasses import dataclass, field
import threading
import time
from typing import Callable, Dict, List, Optional, Sequence, Tuple

from geometry_msgs.msg import PoseStamped
import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile
from sensor_msgs.msg import JointState

from sik_interfaces.msg import IKSolutionArray

GOAL_TOPIC = '/sik_node/goal'
ANSWER_TOPIC = '/sik_node/solutions'
#: A joint change between consecutive followed answers larger than this is a posture flip [rad]
#: (on a smooth path sampled at 100 Hz or more, consecutive answers differ by milliradians).
FLIP = 0.3


def circle_goals(centre: Sequence[float], radius: float, count: int, period: float,
                 rate: float) -> np.ndarray:
    """``count`` positions along a circle in the x-y plane, ``rate`` a second, ``period`` a turn.

    Args:
        centre: the circle's centre [m].
        radius: its radius [m].
        count: goals.
        period: time of one turn [s].
        rate: goals per second [Hz].
    """
    t = np.arange(count) / rate
    angle = 2 * np.pi * t / period
    c = np.asarray(centre, float)
    return np.stack([c[0] + radius * (np.cos(angle) - 1), c[1] + radius * np.sin(angle),
                     np.full(count, c[2])], axis=1)


@dataclass
class Received:
    """One answer as it arrived."""

    at: float                      # time.monotonic() on arrival [s]
    stamp_ns: int                  # its header stamp [ns]
    code: int
    q: Optional[np.ndarray]        # the first solution, if any
    replaced: int
    message: str


@dataclass
class StreamRecord:
    """What one stream sent and got back."""

    rate: float
    positions: np.ndarray          # (N, 3) goal positions [m]
    orientation: Optional[np.ndarray]
    sent_at: np.ndarray            # (N,) time.monotonic() at publication [s]
    stamps_ns: np.ndarray          # (N,) the goals' header stamps [ns]
    answers: List[Received] = field(default_factory=list)


class GoalStreamClient:
    """A node that publishes goals and records answers, spun by its own thread."""

    def __init__(self, joint_names: Sequence[str], follow: bool = False,
                 frame_id: str = '', node_name: str = 'sik_stream_client',
                 goal_topic: str = GOAL_TOPIC, answer_topic: str = ANSWER_TOPIC,
                 context=None) -> None:
        """Create the node (rclpy must be initialised).

        Args:
            joint_names: the arm's joints (for the simulated arm's ``joint_states``).
            follow: publish each successful answer's first solution on ``joint_states``.
            frame_id: the goals' frame.
            node_name: this client's node name.
            goal_topic: where goals go.
            answer_topic: where answers come from.
            context: the rclpy context (default: the global one).
        """
        self.joint_names = list(joint_names)
        self.follow = follow
        self.frame_id = frame_id
        self.node = rclpy.create_node(node_name, context=context)
        self._pub = self.node.create_publisher(PoseStamped, goal_topic, QoSProfile(depth=100))
        self._state_pub = self.node.create_publisher(JointState, 'joint_states', 10)
        self._sub = self.node.create_subscription(IKSolutionArray, answer_topic, self._on_answer,
                                                  QoSProfile(depth=10000))
        self._record: Optional[StreamRecord] = None
        self._lock = threading.Lock()
        self._executor = SingleThreadedExecutor(context=context)
        self._executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        try:
            self._executor.spin()
        except Exception:  # shut down under it
            pass

    def wait_for_node(self, timeout: float) -> bool:
        """Wait until the node's goal subscription and answer publisher are matched [s]."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if (self._pub.get_subscription_count() > 0
                    and self._sub.get_publisher_count() > 0):
                return True
            time.sleep(0.05)
        return False

    def _on_answer(self, msg: IKSolutionArray) -> None:
        at = time.monotonic()
        q = (np.array(msg.solutions[0].joint_state.position) if msg.solutions else None)
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        with self._lock:
            record = self._record
            if record is not None:
                record.answers.append(Received(at, stamp, msg.error_code, q,
                                               msg.goals_replaced, msg.message))
        if self.follow and q is not None and msg.error_code == 1:
            self.publish_state(q)

    def publish_state(self, q: np.ndarray) -> None:
        """Publish ``q`` on ``joint_states`` (the simulated arm is there now)."""
        state = JointState(name=self.joint_names, position=[float(v) for v in q])
        state.header.stamp = self.node.get_clock().now().to_msg()
        self._state_pub.publish(state)

    def run(self, positions: np.ndarray, rate: float,
            orientation: Optional[Sequence[float]] = None, settle: float = 0.5,
            make_msg: Optional[Callable[[int, PoseStamped], None]] = None) -> StreamRecord:
        """Publish one goal per position at ``rate`` Hz, then wait ``settle`` s for answers.

        Args:
            positions: (N, 3) goal positions [m].
            rate: goals per second [Hz].
            orientation: the goals' quaternion x y z w (None: identity, for position goals).
            settle: time to wait for the last answers [s].
            make_msg: edits each goal before it is sent (hostile streams).
        """
        positions = np.asarray(positions, float)
        n = len(positions)
        quat = np.asarray(orientation if orientation is not None else (0, 0, 0, 1), float)
        record = StreamRecord(rate, positions, None if orientation is None else quat,
                              np.zeros(n), np.zeros(n, dtype=np.int64))
        with self._lock:
            self._record = record
        start = time.monotonic() + 0.01
        for i, p in enumerate(positions):
            due = start + i / rate
            while True:
                left = due - time.monotonic()
                if left <= 0:
                    break
                time.sleep(left if left > 0.002 else 0)
            msg = PoseStamped()
            msg.header.frame_id = self.frame_id
            stamp = time.time_ns()
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
            pos, ori = msg.pose.position, msg.pose.orientation
            pos.x, pos.y, pos.z = (float(v) for v in p)
            ori.x, ori.y, ori.z, ori.w = (float(v) for v in quat)
            if make_msg is not None:
                make_msg(i, msg)
            record.stamps_ns[i] = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            record.sent_at[i] = time.monotonic()
            self._pub.publish(msg)
        time.sleep(settle)
        with self._lock:
            self._record = None
        return record

    def close(self) -> None:
        """Stop spinning and destroy the node."""
        self._executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()

    def __enter__(self) -> 'GoalStreamClient':
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _pct(values: Sequence[float], q: float) -> float:
    return float(np.percentile(values, q)) if len(values) else float('nan')


def stream_report(record: StreamRecord,
                  fk: Optional[Callable[[np.ndarray], Tuple[np.ndarray, np.ndarray]]] = None,
                  position_tolerance: float = 1e-4, orientation_tolerance: float = 1e-3,
                  flip: float = FLIP) -> Dict[str, float]:
    """The figures of one stream (times in ms).

    Args:
        record: what was sent and received.
        fk: ``fk(q) -> (position, quaternion x y z w)`` to check every successful answer's
            first solution (None: not checked).
        position_tolerance: a checked solution is valid within this position error [m].
        orientation_tolerance: and this orientation error for pose goals [rad].
        flip: a joint change between consecutive successful answers above this is a flip [rad].
    """
    index = {int(s): i for i, s in enumerate(record.stamps_ns)}
    n = len(record.sent_at)
    answers = record.answers
    matched = [(index.get(a.stamp_ns), a) for a in answers]
    stamped = [(i, a) for i, a in matched if i is not None]
    latency, order = [], []
    newest = -1
    out_of_order = 0
    for i, a in stamped:
        latency.append((a.at - record.sent_at[i]) * 1e3)
        if i <= newest:
            out_of_order += 1
        newest = max(newest, i)
        order.append(i)
    # staleness: from each goal until an answer to it or to a newer goal arrived
    first_at = np.full(n, np.inf)
    for i, a in stamped:
        first_at[i] = min(first_at[i], a.at)
    answered_by = np.minimum.accumulate(first_at[::-1])[::-1] if n else first_at
    staleness = (answered_by - record.sent_at) * 1e3
    finite = staleness[np.isfinite(staleness)]
    codes: Dict[int, int] = {}
    for a in answers:
        codes[a.code] = codes.get(a.code, 0) + 1
    flips, checked, invalid = 0, 0, 0
    previous = None
    for i, a in stamped:
        if a.code != 1 or a.q is None:
            continue
        if previous is not None and np.max(np.abs(a.q - previous)) > flip:
            flips += 1
        previous = a.q
        if fk is not None:
            checked += 1
            p, quat = fk(a.q)
            perr = np.linalg.norm(p - record.positions[i])
            ok = perr <= position_tolerance
            if record.orientation is not None:
                dot = abs(float(np.dot(quat, record.orientation)))
                ok = ok and 2 * np.arccos(min(dot, 1.0)) <= orientation_tolerance
            invalid += not ok
    last = (first_at[-1] - record.sent_at[-1]) * 1e3 if n else float('nan')
    return {
        'rate': record.rate, 'goals': n, 'answers': len(answers),
        'answered': len({i for i, _ in stamped}) / n if n else float('nan'),
        'stamped': len(stamped), 'unstamped': len(answers) - len(stamped),
        'out_of_order': out_of_order,
        'latency_p50': _pct(latency, 50), 'latency_p99': _pct(latency, 99),
        'staleness_p50': _pct(finite, 50), 'staleness_p99': _pct(finite, 99),
        'never_answered': int(np.sum(~np.isfinite(staleness))),
        'last_answer': last,
        'replaced_reported': sum(a.replaced for a in answers),
        'success': codes.get(1, 0), 'timeout': codes.get(-5, 0),
        'joint_jump': codes.get(-7, 0),
        'other_codes': sum(v for k, v in codes.items() if k not in (1, -5, -7)),
        'flips': flips, 'checked': checked, 'invalid': invalid,
    }
