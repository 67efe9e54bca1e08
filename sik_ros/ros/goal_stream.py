"""``~/goal`` -> ``~/solutions``: pose goal streams answered like a servo, newest goal first.

One thread of its own (with a node of its own for the subscription) takes every goal queued,
keeps the newest (the others are counted as replaced:
:class:`~sik_ros.serving.stream.LatestGoal`), solves it with ``goal_num_solutions`` solutions
seeded by the previous answer (or by ``joint_states`` where that is newer) and ranked by
distance to that seed, and publishes the answer under the goal's own header. So answers leave
in the order of their goals, and none is published after the answer to a newer goal. An answer
whose best solution is farther from the seed than ``goal_max_joint_step`` in any joint is
``JOINT_JUMP``: given, but neither followed by the next goal's seed nor commanded. With
``command_format`` set, each answer is also sent to a ros2_control controller, one step at most
the joint velocity limits times the goal period away from the last command
(:class:`~sik_ros.serving.stream.ServoState`). Markers are drawn at most ``goal_marker_rate``
times a second.

The stream takes a narrow :class:`StreamPort` of its node (solvers, parameters, the seed,
publishing markers, the guard and the clock), not the node; one clock, the node's ROS clock,
stamps the goals' arrival and times the servo (``joint_states`` arrival times are system time,
the same clock unless ``use_sim_time``).
"""

from dataclasses import dataclass
import math
import threading
import time
from typing import Any, Callable, Optional, Tuple

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
import numpy as np
from rclpy.executors import (ExternalShutdownException, ShutdownException,
                             SingleThreadedExecutor)
from std_msgs.msg import Float64MultiArray, Header
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from sik_interfaces.msg import IKSolutionArray
from sik_interfaces.srv import SolveIK
from sik_ros.ros import conversions as conv
from sik_ros.ros.ik_service import Arm, checked_goal, solution_msgs
from sik_ros.ros.side_node import side_node, take_newest
from sik_ros.serving.stream import LatestGoal, max_joint_step, ServoState

R = SolveIK.Response
#: Goals the subscription's queue keeps (KEEP_LAST) until the executor's next turn, which takes
#: them all (the newest is answered, the others counted as replaced); a burst of more within one
#: turn loses the oldest before they are counted.
GOAL_QUEUE = 1000
#: Longest wait of the answering thread for a goal before it looks whether it must stop [s].
WAIT = 0.1


def _stamp_seconds(stamp: Time) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


@dataclass(frozen=True)
class StreamPort:
    """What the goal stream uses of its node.

    Attributes:
        params: the parameters in force.
        arm: the served arm (joint names, base frame), or None.
        solvers: where to solve, or None.
        measured: the latest ``joint_states`` as a seed (clipped to the limits) and when it
            arrived [s]; Nones for none.
        answer: the node's request guard (``RequestGuard.answer``): refusals, codes, counts.
        closing: whether the node is shutting down.
        markers: draws solutions on ``~/markers`` when someone listens
            (``markers(solutions, header, position, orientation)``); returns whether it did.
        clock: the node's clock [s] (ROS time).
        logger: the node's logger.
    """

    params: Callable[[], Any]
    arm: Callable[[], Optional[Arm]]
    solvers: Callable[[], Any]
    measured: Callable[[], Tuple[Optional[np.ndarray], Optional[float]]]
    answer: Callable[..., Any]
    closing: Callable[[], bool]
    markers: Callable[..., bool]
    clock: Callable[[], float]
    logger: Any


class GoalStream:
    """The ``~/goal`` subscription and the thread that answers it, for one node."""

    def __init__(self, node, port: StreamPort) -> None:
        """Subscribe to ``~/goal`` and start the answering thread.

        Args:
            node: the ROS node the topics belong to (publishers and the subscription only).
            port: what the answers use of the node.
        """
        self.port = port
        self.mailbox: LatestGoal = LatestGoal()
        self.servo: Optional[ServoState] = None
        self._answers_pub = node.create_publisher(IKSolutionArray, '~/solutions', 10)
        self._command_pub = None
        params = port.params()
        self._format = params.command_format
        if self._format != 'none':
            kind = (Float64MultiArray if self._format == 'float64_multi_array'
                    else JointTrajectory)
            self._command_pub = node.create_publisher(kind, params.command_topic, 10)
        self._last_markers = -math.inf
        self.commands = 0
        # The subscription is a node of its own, spun by the answering thread: a goal is taken
        # and answered on one thread, with no executor turn of the services' between them.
        self._node = side_node(node, 'goal_stream')
        self._sub = self._node.create_subscription(
            PoseStamped, node.resolve_topic_name('~/goal'), self._on_goal, GOAL_QUEUE)
        self._executor = SingleThreadedExecutor(context=node.context)
        self._executor.add_node(self._node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name='sik_goal_stream', daemon=True)
        self._thread.start()

    # -- taking goals (the answering thread) ------------------------------------------------------

    def _on_goal(self, msg: PoseStamped) -> None:
        """The executor took ``msg``: hand it, or a newer goal queued behind it, over."""
        self._take_newest(msg)

    def _take_newest(self, msg: Optional[PoseStamped] = None) -> bool:
        """Take every queued goal; hand the newest over, count the others as replaced.

        Returns:
            Whether there was a goal.
        """
        arrived = self.port.clock()
        newest, _, count = take_newest(self._sub, PoseStamped)
        skipped = count if msg is not None else count - 1
        msg = newest if newest is not None else msg
        if msg is None:
            return False
        self.mailbox.put((msg, arrived), skipped)
        return True

    def reset(self, velocity_limits: Optional[np.ndarray]) -> None:
        """Start a new stream (a bundle loaded: its velocity limits; None: unloaded)."""
        self.servo = (None if velocity_limits is None
                      else ServoState(velocity_limits, clock=self.port.clock))

    # -- the answering thread ---------------------------------------------------------------------

    def _serve(self) -> None:
        while not self._stop.is_set():
            if not self._take_newest():  # none queued: wait for one
                try:
                    self._executor.spin_once(timeout_sec=WAIT)
                except (ExternalShutdownException, ShutdownException):
                    return
            taken = self.mailbox.take(0.0)
            if taken is None:
                continue
            (msg, arrived), replaced = taken
            try:
                self._answer(msg, arrived, replaced)
            except Exception as exc:  # the stream goes on whatever one answer does
                self.port.logger.error(
                    f'goal: answering failed: {type(exc).__name__}: {exc}',
                    throttle_duration_sec=5.0)

    def _answer(self, msg: PoseStamped, arrived: float, replaced: int) -> None:
        port = self.port
        out = IKSolutionArray(header=msg.header, goals_replaced=replaced, joint_step=-1.0)
        response = port.answer('goal', SolveIK.Response(),
                               lambda r: self._solve(msg, arrived, out))
        if port.closing():
            return
        out.error_code, out.message = response.error_code, response.message
        if response.error_code not in (R.SUCCESS, R.JOINT_JUMP):
            out.solutions, out.num_families = [], 0
        self._answers_pub.publish(out)

    def _solve(self, msg: PoseStamped, arrived: float, out: IKSolutionArray):
        """Solve one goal into ``out``; its code and message (raises on bad input)."""
        port = self.port
        p, arm, servo, solvers = port.params(), port.arm(), self.servo, port.solvers()
        if servo is None or arm is None or solvers is None:
            return R.TIMEOUT, 'sik_node has no bundle loaded'
        position, orientation = checked_goal(arm, msg, p.goal_use_orientation, 'goal')
        if p.use_joint_states:
            state, received = port.measured()
            if received is not None and received > servo.measured_at:
                servo.measured(state, received)  # newer than the one in use
        seed = servo.seed()
        result = solvers.solve(position, orientation, p.goal_num_solutions, seed=seed,
                               refine=p.refine, timeout=p.goal_timeout)
        code, text = conv.result_code(result, False, p.goal_timeout)
        out.solutions = solution_msgs(result, arm, msg.header)
        out.num_families = int(result.num_families)
        if code == R.SUCCESS and result.solutions:
            best = np.asarray(result.solutions[0].q, float)
            if seed is not None:
                step = max_joint_step(seed, best)
                out.joint_step = step
                bound = p.goal_max_joint_step
                if bound > 0 and step > bound:
                    servo_note = (f'the best solution is {step:.3f} rad from the seed in one '
                                  f'joint, over goal_max_joint_step {bound:g} (a limit, a '
                                  f'singularity or another posture family): not followed')
                    servo.jumps += 1
                    self._markers(result, msg.header, position, orientation)
                    return R.JOINT_JUMP, f'{servo_note} ({text})'
            servo.follow(best)
            self._command(best, msg.header, arrived)
        self._markers(result, msg.header, position, orientation)
        return code, text

    def _command(self, q: np.ndarray, header: Header, arrived: float) -> None:
        pub, servo = self._command_pub, self.servo
        if pub is None or servo is None:
            return
        stamp = _stamp_seconds(header.stamp)
        goal_time = stamp if stamp > 0 else arrived
        period = servo.period(goal_time)
        target = servo.command(q, goal_time)
        if target is None:
            self.port.logger.warning(
                'command output: no joint_states and no command yet, so the first step cannot '
                'be bounded: not commanding (set use_joint_states:=true)',
                throttle_duration_sec=5.0)
            return
        values = [float(v) for v in target]
        if self._format == 'float64_multi_array':
            pub.publish(Float64MultiArray(data=values))
        else:
            point = JointTrajectoryPoint(positions=values,
                                         time_from_start=conv.duration_from_seconds(period))
            arm = self.port.arm()
            pub.publish(JointTrajectory(joint_names=list(arm.joint_names) if arm else [],
                                        points=[point]))
        self.commands += 1

    def _markers(self, result, header: Header, position, orientation) -> None:
        rate = self.port.params().goal_marker_rate
        now = time.monotonic()
        if rate <= 0 or now - self._last_markers < 1.0 / rate:
            return
        if self.port.markers(result.solutions, header, position, orientation):
            self._last_markers = now

    def close(self) -> None:
        """Stop the answering thread (it finishes the answer in hand) and its node."""
        self._stop.set()
        self.mailbox.close()
        self._thread.join(timeout=2.0)
        self._executor.shutdown(timeout_sec=0)
        self._node.destroy_node()
