"""sik_node's health on ``/diagnostics``, about once a second, and in its log at shutdown.

One ``diagnostic_msgs/DiagnosticStatus`` named ``sik_node: <node name>`` with the level (OK,
WARN, ERROR), the bundle, the node's state, the request rate and the latency p50/p99 over the
last :data:`WINDOW` seconds, failures by code since start, the solver processes' health, the
robot_description check and the ``~/goal`` stream's counts (goals received, replaced by a newer
one, answered JOINT_JUMP, commands sent). :class:`RequestStats` (plain Python) keeps the
figures; it hears every answer through :class:`~sik_ros.ros.guard.RequestGuard`'s listeners.
"""

from collections import Counter, deque
from dataclasses import dataclass, field
import threading
import time
from typing import Callable, Deque, Dict, List, Tuple

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
import numpy as np
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup

from sik_interfaces.srv import SolveIK
from sik_ros.ros.conversions import ERROR_NAMES

#: The recent window of the request rate and latency percentiles [s].
WINDOW = 60.0
#: Most answers the window keeps (a busier node's window is shorter than WINDOW).
MAX_SAMPLES = 20000
#: Time between two /diagnostics messages [s].
PERIOD = 1.0
R = SolveIK.Response
#: Codes that say the node (not the request) failed: recent ones make the status ERROR / WARN.
ERROR_CODES = (R.INTERNAL_ERROR,)
WARN_CODES = (R.TIMEOUT,)
OK, WARN, ERROR = DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR


@dataclass
class Figures:
    """A snapshot of the request statistics.

    Attributes:
        total: answers since start.
        window: the span the rate and percentiles cover [s].
        rate: answers per second over ``window``.
        p50, p99: answer latency percentiles over ``window`` [s] (nan without answers).
        failures: answers that were not SUCCESS since start, by code name.
        recent: codes of the answers in the window, counted.
    """

    total: int
    window: float
    rate: float
    p50: float
    p99: float
    failures: Dict[str, int] = field(default_factory=dict)
    recent: Dict[int, int] = field(default_factory=dict)

    def summary(self) -> str:
        """The figures as one line."""
        failures = ', '.join(f'{k} {v}' for k, v in sorted(self.failures.items())) or 'none'
        latency = ('no answers in the window' if np.isnan(self.p50) else
                   f'latency p50 {self.p50 * 1e3:.2f} ms, p99 {self.p99 * 1e3:.2f} ms')
        return (f'{self.total} requests ({self.rate:.2f}/s over the last {self.window:.0f} s, '
                f'{latency}); failures: {failures}')


class RequestStats:
    """Answer codes and latencies, recent and since start; safe from every executor thread."""

    def __init__(self, window: float = WINDOW, clock: Callable[[], float] = time.monotonic):
        self.window = window
        self._clock = clock
        self._start = clock()
        self._recent: Deque[Tuple[float, int, float]] = deque(maxlen=MAX_SAMPLES)
        self._codes: Counter = Counter()
        self._lock = threading.Lock()

    def record(self, where: str, code: int, seconds: float) -> None:
        """Count one answer (a :class:`~sik_ros.ros.guard.RequestGuard` listener)."""
        with self._lock:
            self._recent.append((self._clock(), int(code), float(seconds)))
            self._codes[int(code)] += 1

    def figures(self) -> Figures:
        """The statistics now."""
        now = self._clock()
        with self._lock:
            while self._recent and self._recent[0][0] < now - self.window:
                self._recent.popleft()
            recent = list(self._recent)
            codes = dict(self._codes)
        span = min(self.window, max(now - self._start, 1e-9))
        if len(recent) == MAX_SAMPLES:
            span = max(now - recent[0][0], 1e-9)
        latencies = np.array([r[2] for r in recent])
        p50, p99 = (np.percentile(latencies, [50, 99]) if len(latencies)
                    else (float('nan'), float('nan')))
        failures = {ERROR_NAMES.get(c, str(c)): n for c, n in codes.items() if c != R.SUCCESS}
        return Figures(sum(codes.values()), span, len(recent) / span, float(p50), float(p99),
                       failures, dict(Counter(r[1] for r in recent)))


class NodeDiagnostics:
    """Publishes the node's status on ``/diagnostics`` every :data:`PERIOD` seconds."""

    def __init__(self, node):
        """Listen to ``node.guard`` and start the publisher and its timer (a SikNode)."""
        self.node = node
        self.stats = RequestStats()
        node.guard.listeners.append(self.stats.record)
        self.name = f'sik_node: {node.get_fully_qualified_name()}'
        self._pub = node.create_publisher(DiagnosticArray, '/diagnostics', 10)
        # its own group: the status goes on while a lifecycle transition loads the bundle
        self._timer = node.create_timer(PERIOD, self.publish,
                                        callback_group=MutuallyExclusiveCallbackGroup())

    def state(self) -> str:
        """The node's serving state: active, inactive, unconfigured or shutting down."""
        node = self.node
        if node.guard.closing:
            return 'shutting down'
        managed = getattr(node, 'managed_state', None)
        if managed is not None:
            return managed
        return 'active' if node.ik is not None else 'unconfigured'

    def status(self) -> DiagnosticStatus:
        """The node's status now."""
        node = self.node
        figures = self.stats.figures()
        state = self.state()
        ik = node.ik
        levels: List[Tuple[int, str]] = []
        if state != 'active':
            levels.append((WARN, state))
        if node.mismatch:
            levels.append((ERROR, 'the bundle does not fit the robot_description'))
        if node.no_robot:
            levels.append((ERROR if node.no_robot.startswith('robot_description') else WARN,
                           node.no_robot))
        health = node.solvers.health() if node.solvers is not None else None
        if health is None:
            processes = (f'none ({node.workers} solver threads)' if ik is not None
                         else 'not started')
        else:
            processes = (f'{health.ready}/{health.processes} ready, {health.restarts} '
                         f'restarts, {health.failed_starts} failed starts')
            if health.ready == 0:
                levels.append((ERROR, 'no solver process serving'))
            elif health.ready < health.processes:
                levels.append((WARN, f'{health.ready} of {health.processes} solver processes'))
        for codes, level in ((ERROR_CODES, ERROR), (WARN_CODES, WARN)):
            recent = sum(figures.recent.get(c, 0) for c in codes)
            if recent:
                names = '/'.join(ERROR_NAMES[c] for c in codes)
                levels.append((level, f'{recent} {names} in the last {figures.window:.0f} s'))
        level = max((lv for lv, _ in levels), default=OK)
        message = '; '.join(m for _, m in levels) or 'serving'
        values = [
            ('bundle', '(none loaded)' if ik is None else str(ik.bundle) if ik.learned
             else '(table of configurations)'),
            ('state', state),
            ('requests', str(figures.total)),
            ('requests per second', f'{figures.rate:.3f}'),
            ('window [s]', f'{figures.window:.1f}'),
            ('latency p50 [ms]', _ms(figures.p50)),
            ('latency p99 [ms]', _ms(figures.p99)),
            ('in flight', str(node.in_flight)),
            ('solver processes', processes),
            ('robot_description', self.description_check()),
        ]
        if node.follower is not None:
            values += node.follower.values()
        stream = node.goal_stream
        if stream is not None:
            servo = stream.servo
            goal_health = (node.stream_solvers.health()
                           if getattr(node, 'stream_solvers', None) is not None else None)
            if goal_health is not None:
                values.append(('goal solver process',
                               f'{goal_health.ready}/{goal_health.processes} ready, '
                               f'{goal_health.restarts} restarts'))
            values += [('goals received', str(stream.mailbox.received)),
                       ('goals replaced', str(stream.mailbox.replaced)),
                       ('goal joint jumps', str(servo.jumps if servo is not None else 0)),
                       ('commands sent', str(stream.commands))]
        values += [(f'failures {name}', str(n)) for name, n in sorted(figures.failures.items())]
        return DiagnosticStatus(level=level, name=self.name, message=message,
                                hardware_id=str(ik.bundle) if ik is not None else '',
                                values=[KeyValue(key=k, value=v) for k, v in values])

    def description_check(self) -> str:
        """The robot_description check: not given, matching, or how it differs."""
        node = self.node
        if node.mismatch:
            return node.mismatch
        if node.follower is not None:
            return node.no_robot or 'served'
        if not (node.params.robot_description or node.description_check.description):
            return 'not given'
        return 'matches the bundle' if node.ik is not None else 'not checked (no bundle)'

    def publish(self) -> None:
        """Publish the status on /diagnostics."""
        msg = DiagnosticArray(status=[self.status()])
        msg.header.stamp = self.node.get_clock().now().to_msg()
        self._pub.publish(msg)

    def log_summary(self) -> None:
        """Log the statistics in one line (at shutdown)."""
        status = self.status()
        values = {kv.key: kv.value for kv in status.values}
        self.node.get_logger().info(
            f'{self.stats.figures().summary()}; solver processes: '
            f'{values["solver processes"]}; robot_description: {values["robot_description"]}')


def _ms(seconds: float) -> str:
    return 'nan' if np.isnan(seconds) else f'{seconds * 1e3:.3f}'
