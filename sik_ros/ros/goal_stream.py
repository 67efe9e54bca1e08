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
"""

import math
import threading
import time
from typing import Optional

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
from sik_ros.ros.ik_service import solution_msgs
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


class GoalStream:
    """The ``~/goal`` subscription and the thread that answers it, for one :class:`SikNode`."""

    def __init__(self, node) -> None:
        """Subscribe to ``~/goal`` and start the answering thread.

        Args:
            node: the :class:`~sik_ros.ros.node.SikNode` (its solvers, parameters and guard).
        """
        self.node = node
        self.mailbox: LatestGoal = LatestGoal()
        self.servo: Optional[ServoState] = None
        self._answers_pub = node.create_publisher(IKSolutionArray, '~/solutions', 10)
        self._command_pub = None
        self._format = node.params.command_format
        if self._format != 'none':
            kind = (Float64MultiArray if self._format == 'float64_multi_array'
                    else JointTrajectory)
            self._command_pub = node.create_publisher(kind, node.params.command_topic, 10)
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
        arrived = time.monotonic()
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
                      else ServoState(velocity_limits, clock=time.time))

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
                self.node.get_logger().error(
                    f'goal: answering failed: {type(exc).__name__}: {exc}',
                    throttle_duration_sec=5.0)

    def _answer(self, msg: PoseStamped, arrived: float, replaced: int) -> None:
        node = self.node
        out = IKSolutionArray(header=msg.header, goals_replaced=replaced, joint_step=-1.0)
        response = node.guard.answer('goal', SolveIK.Response(),
                                     lambda r: self._solve(msg, arrived, out))
        if node.closing:
            return
        out.error_code, out.message = response.error_code, response.message
        if response.error_code not in (R.SUCCESS, R.JOINT_JUMP):
            out.solutions, out.num_families = [], 0
        self._answers_pub.publish(out)

    def _solve(self, msg: PoseStamped, arrived: float, out: IKSolutionArray):
        """Solve one goal into ``out``; its code and message (raises on bad input)."""
        node = self.node
        p, arm, servo = node.params, node.arm, self.servo
        if servo is None or arm is None:
            return R.TIMEOUT, 'sik_node has no bundle loaded'
        arm.check_frame(msg.header.frame_id, 'goal')
        position, orientation = conv.goal_from_pose(msg.pose, p.goal_use_orientation)
        if p.use_joint_states:
            state, received = node.joint_states.latest()
            if received is not None and received > servo.measured_at:
                servo.measured(node.seed_from_state(state), received)  # newer than the one in use
        seed = servo.seed()
        result = node.solvers.solve(position, orientation, p.goal_num_solutions, seed=seed,
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
            self.node.get_logger().warning(
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
            pub.publish(JointTrajectory(joint_names=list(self.node.arm.joint_names),
                                        points=[point]))
        self.commands += 1

    def _markers(self, result, header: Header, position, orientation) -> None:
        node = self.node
        rate = node.params.goal_marker_rate
        now = time.monotonic()
        if rate <= 0 or now - self._last_markers < 1.0 / rate or not node.want_markers():
            return
        self._last_markers = now
        node.publish_markers(result.solutions, header, position, orientation)

    def close(self) -> None:
        """Stop the answering thread (it finishes the answer in hand) and its node."""
        self._stop.set()
        self.mailbox.close()
        self._thread.join(timeout=2.0)
        self._executor.shutdown(timeout_sec=0)
        self._node.destroy_node()
