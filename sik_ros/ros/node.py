"""sik_node: the ROS 2 node over :class:`~sik_ros.solver.SelectiveIK`.

Service ``~/solve_ik`` (``sik_interfaces/srv/SolveIK``), service ``~/solve_ik_batch``
(``sik_interfaces/srv/SolveIKBatch``: many targets, :mod:`~sik_ros.ros.batch_service`),
service ``~/solve_path`` (``sik_interfaces/srv/SolvePath``; their callbacks:
:mod:`~sik_ros.ros.requests`), topics ``~/goal`` ->
``~/solutions`` (a stream, newest goal first: :mod:`~sik_ros.ros.goal_stream`),
``joint_states`` (optional seed), ``~/markers`` (RViz) and an optional command output for
ros2_control. Started by :mod:`sik_ros.ros.run` (the ``sik_node`` command): ``sik_node
--ros-args --params-file config/panda.yaml``. See docs/interfaces.md.

The node is wiring: its constructor declares the parameters, loads the bundle named by
``robot`` or ``model_dir`` (:mod:`~sik_ros.ros.named_bundle`) or follows the arm of
robot_description (:mod:`~sik_ros.ros.arm_follower`), starts the solvers and creates the ROS
interfaces; each callback hands its request to :class:`~sik_ros.ros.guard.RequestGuard` with a
handler from :mod:`~sik_ros.ros.ik_service`, :mod:`~sik_ros.ros.batch_service` or
:mod:`~sik_ros.ros.path_service`; ``~/goal`` is answered by a thread of its own
(:class:`~sik_ros.ros.goal_stream.GoalStream`).
"""

from dataclasses import fields, replace
import gc
import threading
from typing import List, Optional

from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.exceptions import InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
from visualization_msgs.msg import MarkerArray

from sik_interfaces.srv import SolveIK, SolveIKBatch, SolvePath
from sik_ros.errors import SikError
from sik_ros.ros.arm_follower import ArmFollower
from sik_ros.ros.batch_service import GiveWay
from sik_ros.ros.diagnostics import NodeDiagnostics
from sik_ros.ros.goal_stream import GoalStream, StreamPort
from sik_ros.ros.guard import log_at, RequestGuard
from sik_ros.ros.ik_service import Arm, solver_settings
from sik_ros.ros.joint_states import JointStateTap
from sik_ros.ros.markers import MarkerOutput
from sik_ros.ros.moveit_ik import serve_moveit
from sik_ros.ros.named_bundle import DescriptionCheck, load_named, StartupError
from sik_ros.ros.params import declarations, NodeParams, validate
from sik_ros.ros.requests import RequestHandlers
from sik_ros.serving.pool import single_threaded
from sik_ros.serving.solvers import make_solvers, Solver
from sik_ros.solver import SelectiveIK, SolverConfig

NODE_NAME = 'sik_node'
#: Depth of the services' request queues. ROS 2's default for services keeps the last 10
#: requests: with more clients waiting than that while every executor thread is busy, Fast
#: DDS drops the oldest unread requests, and their clients wait for a resend
#: (docs/benchmarks.md, bench/soak.py).
SERVICE_QUEUE = 256
#: Executor threads; the solver instances are one per thread and one for the ~/goal stream.
WORKERS = 4
#: Longest time the main thread waits in the executor before it checks for signals [s].
SPIN_PERIOD = 0.1
#: Seconds solvers replaced by others (a learned model swapped in) keep serving the requests
#: they had before they are closed.
RETIRE_AFTER = 10.0
#: Period of the check on the background learning [s].
LEARNING_POLL = 1.0
Response = SolveIK.Response


class SikNode(RequestHandlers, Node):
    """The IK node: loads a bundle, answers its services and ``~/goal``.

    The services: ``~/solve_ik``, ``~/solve_ik_batch``, ``~/solve_path``, and MoveIt's
    ``/compute_ik`` and ``/compute_fk``.
    """

    def __init__(self, workers: int = WORKERS, managed: bool = False, **kwargs):
        """Declare the parameters, load the bundle, start the solvers, create the interfaces.

        Args:
            workers: executor threads (and solver clones without solver processes).
            managed: leave the bundle and the solvers to :meth:`start` (a managed node's
                configure transition, :mod:`sik_ros.ros.lifecycle`); requests are refused
                until then.
            **kwargs: passed to :class:`rclpy.node.Node` (e.g. ``parameter_overrides``).

        Raises:
            StartupError: bad parameter values, a missing, corrupt or mismatched bundle, or
                solver processes that cannot start.
        """
        super().__init__(NODE_NAME, **kwargs)
        single_threaded()
        self.workers = workers
        self._declare_parameters()
        self._params = self._read_parameters()
        self.shutdown_grace = self._params.shutdown_grace
        self._ik: Optional[SelectiveIK] = None
        self.arm: Optional[Arm] = None
        self.solvers: Optional[Solver] = None
        #: the ~/goal stream's solver process (goal_solver_process), or None: the stream solves
        #: with ``solvers``
        self.stream_solvers: Optional[Solver] = None
        #: the robot_description topic held to a bundle named by robot or model_dir
        self.description_check = DescriptionCheck(Response.ROBOT_MISMATCH,
                                                  self.get_logger().info,
                                                  self.get_logger().error)
        #: why no arm is served (an arm from robot_description not yet, or not, servable)
        self._no_robot: Optional[str] = None
        p = self._params
        #: the arm of robot_description, when no bundle is named (robot and model_dir empty)
        self.follower = None if (p.robot or p.model_dir) else ArmFollower(
            self, p, self.get_logger().info, self.get_logger().error)
        self.guard = RequestGuard(self.get_logger())
        self.guard.refusals.append(self.description_check.refusal)
        self.guard.refusals.append(self._no_robot_refusal)
        #: where ~/solve_ik_batch requests wait for the others between their targets
        self.give_way = GiveWay(lambda: self.guard.in_flight)
        self.guard.listeners.append(self.give_way.answered)
        self.diagnostics = NodeDiagnostics(self)
        self.goal_stream: Optional[GoalStream] = None
        if not managed:
            self.start()
        self.joint_states = JointStateTap(self)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)
        self._create_interfaces()

    def start(self) -> None:
        """Load the bundle, start and warm up the solvers.

        Raises:
            StartupError: bad parameter values, a missing, corrupt or mismatched bundle, or
                solver processes that cannot start; nothing is left loaded.
        """
        reason = validate(self._params)
        if reason is not None:
            raise StartupError(f'bad parameters: {reason}')
        if self.follower is not None:
            text = self._params.robot_description
            if text:
                self.follower.take(text, 'parameter')
            else:
                self.refuse('waiting for robot_description (the parameter is empty: listening '
                            f'on {self.resolve_topic_name("robot_description")})')
                self.get_logger().info(self._no_robot)
            return
        ik = load_named(self._params, solver_settings(self._params))
        try:
            self.install(ik, self._params.solver_processes)
        except SikError as exc:
            raise StartupError(f'cannot start the solver processes: {exc}') from exc
        self.description_check.check(ik)
        self.get_logger().info(
            f'ready: bundle {ik.bundle} ({", ".join(ik.goals)} goals, '
            f'{len(ik.joint_names)} joints {ik.robot.base_frame} -> '
            f'{ik.robot.tip_frame}), {self.workers} executor threads, '
            f'{self._params.solver_processes} solver processes'
            + (', ~/goal in a solver process of its own' if self.stream_solvers else ''))

    def install(self, ik: SelectiveIK, processes: int) -> None:
        """Serve ``ik`` from now on, with ``processes`` solver processes (0: threads).

        Solvers it replaces (a learned model swapped in) finish the requests they hold and
        are closed :data:`RETIRE_AFTER` seconds later.

        Raises:
            SikError: the solver processes cannot start (nothing changes then).
        """
        solvers = make_solvers(ik, processes, self.workers + 1, self._log)
        self.get_logger().info(f'solvers warmed up in {solvers.warm_up_seconds:.2f} s')
        stream = self._stream_solvers(ik)
        old, old_ik, old_stream = self.solvers, self._ik, self.stream_solvers
        self._ik, self.solvers, self.stream_solvers = ik, solvers, stream
        self.arm = Arm(ik.robot.base_frame, list(ik.joint_names))
        same_arm = old_ik is not None and old_ik.robot.manifest() == ik.robot.manifest()
        if self.goal_stream is not None and not same_arm:  # a stream goes on across a swap
            self.goal_stream.reset(ik.robot.velocity_limits)
        self._no_robot = None
        for retired in (old, old_stream):
            if retired is not None:
                timer = threading.Timer(RETIRE_AFTER, retired.close)
                timer.daemon = True
                timer.start()

    def _stream_solvers(self, ik: SelectiveIK) -> Optional[Solver]:
        """The ~/goal stream's solver process (``goal_solver_process``), or None.

        None too for an arm served from its table of configurations (no bundle a process could
        load) and when the process cannot start (logged: the stream then solves in the node).
        """
        if not (self._params.goal_solver_process and ik.learned):
            return None
        try:
            return make_solvers(ik.clone(), 1, 1, self._log)
        except SikError as exc:
            self.get_logger().warning(f'~/goal solver process: cannot start ({exc}); the goal '
                                      f'stream solves in the node')
            return None

    def refuse(self, reason: Optional[str]) -> None:
        """Answer every request ``NO_ROBOT`` with ``reason`` (None: serve again)."""
        self._no_robot = reason

    def solver_config(self) -> SolverConfig:
        """The solver settings of the parameters in force."""
        return SolverConfig(**solver_settings(self._params))

    def _no_robot_refusal(self):
        return (Response.NO_ROBOT, self._no_robot) if self._no_robot else None

    @property
    def no_robot(self) -> Optional[str]:
        """Why no arm is served (requests refused ``NO_ROBOT``), or None."""
        return self._no_robot

    def stop(self) -> None:
        """Stop the solvers and let go of the bundle (its models are freed)."""
        if self.follower is not None:
            self.follower.close()
        solvers, self.solvers = self.solvers, None
        stream, self.stream_solvers = self.stream_solvers, None
        self._ik, self.arm, self.description_check.mismatch = None, None, None
        if self.goal_stream is not None:
            self.goal_stream.reset(None)
        for retired in (solvers, stream):
            if retired is not None:
                retired.close()
        gc.collect()

    def _create_interfaces(self) -> None:
        group = ReentrantCallbackGroup()
        #: ~/markers, drawn off the answers' path, the newest first
        self.markers = MarkerOutput(self.create_publisher(MarkerArray, '~/markers', 5),
                                    lambda: self._params.publish_markers and not self.closing,
                                    self._marker_error)
        requests = QoSProfile(depth=SERVICE_QUEUE, reliability=ReliabilityPolicy.RELIABLE)
        self.create_service(SolveIK, '~/solve_ik', self._on_solve_ik, qos_profile=requests,
                            callback_group=group)
        self.create_service(SolveIKBatch, '~/solve_ik_batch', self._on_solve_ik_batch,
                            qos_profile=requests, callback_group=group)
        self.create_service(SolvePath, '~/solve_path', self._on_solve_path,
                            qos_profile=requests, callback_group=group)
        self.goal_stream = GoalStream(self, self._stream_port())
        if self._ik is not None:
            self.goal_stream.reset(self._ik.robot.velocity_limits)
        self._update_joint_state_subscription()
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                             reliability=ReliabilityPolicy.RELIABLE)
        self.create_subscription(String, 'robot_description', self._on_robot_description,
                                 latched, callback_group=group)
        if self.follower is not None:  # the background learning: its progress, its model
            self.create_timer(LEARNING_POLL, self.follower.poll, callback_group=group)
        self.moveit = serve_moveit(self, group, requests)

    def _stream_port(self) -> StreamPort:
        """What the goal stream uses of this node."""
        def measured():
            state, received = self.joint_states.latest()
            return (None, None) if state is None else (self.seed_from_state(state), received)

        def markers(solutions, header, position, orientation) -> bool:
            if not self.markers.want():
                return False
            self.markers.solutions(self._ik.robot.chain, solutions, header, position,
                                   orientation)
            return True

        return StreamPort(lambda: self._params, lambda: self.arm,
                          lambda: self.stream_solvers or self.solvers,
                          measured, self.guard.answer, lambda: self.closing, markers,
                          lambda: self.get_clock().now().nanoseconds * 1e-9, self.get_logger())

    def _marker_error(self, message: str) -> None:
        self.get_logger().error(message, throttle_duration_sec=10.0)

    def _log(self, level: int, message: str) -> None:
        """Log at a :mod:`logging` level (the solver pool's reports)."""
        log_at(self.get_logger(), level, message)

    # -- parameters ------------------------------------------------------------------------------

    def _declare_parameters(self) -> None:
        """Declare every parameter of :data:`~sik_ros.ros.params.SPECS` with its descriptor.

        Raises:
            StartupError: a value given at start-up is out of its declared range.
        """
        try:
            self.declare_parameters('', declarations())
        except InvalidParameterValueException as exc:
            raise StartupError(f'bad parameters: {exc}') from exc

    def _read_parameters(self) -> NodeParams:
        return NodeParams(**{f.name: self.get_parameter(f.name).value
                             for f in fields(NodeParams)})

    def _on_set_parameters(self, changes: List[Parameter]) -> SetParametersResult:
        """Accept a change only if the resulting set of values is valid."""
        names = {f.name for f in fields(NodeParams)}
        values = replace(self._params, **{c.name: c.value for c in changes if c.name in names})
        reason = validate(values)
        return SetParametersResult(successful=reason is None, reason=reason or '')

    def _after_set_parameters(self, changes: List[Parameter]) -> None:
        """Make accepted values take effect: solvers pick them up at their next request."""
        self._params = self._read_parameters()
        for solvers in (self.solvers, self.stream_solvers):
            if solvers is not None:
                solvers.configure(**solver_settings(self._params))
        self._update_joint_state_subscription()
        self.get_logger().info('parameters set: ' + ', '.join(
            f'{c.name}={c.value!r}' for c in changes))

    def _update_joint_state_subscription(self) -> None:
        self.joint_states.enable(self._params.use_joint_states)

    # -- the bundle ------------------------------------------------------------------------------

    def _on_robot_description(self, msg: String) -> None:
        if self.follower is not None:
            self.follower.take(msg.data, 'topic')
        else:
            self.description_check.take(msg.data, self._ik)

    # -- public state ----------------------------------------------------------------------------

    @property
    def params(self) -> NodeParams:
        """The parameters in force."""
        return self._params

    @property
    def ik(self) -> Optional[SelectiveIK]:
        """The loaded solver (the one the clones and processes are made from); None unloaded."""
        return self._ik

    @property
    def mismatch(self) -> Optional[str]:
        """Why requests are refused (the robot_description differs), or None."""
        return self.description_check.mismatch

    @property
    def closing(self) -> bool:
        """Whether the node is shutting down (new requests are answered TIMEOUT)."""
        return self.guard.closing

    @closing.setter
    def closing(self, value: bool) -> None:
        self.guard.closing = value

    @property
    def in_flight(self) -> int:
        """Requests being answered now."""
        return self.guard.in_flight

    def destroy_node(self) -> None:
        """Log the request statistics, stop the solver processes, then destroy the node."""
        stream = getattr(self, 'goal_stream', None)
        if stream is not None:
            stream.close()
        tap = getattr(self, 'joint_states', None)
        if tap is not None:
            tap.close()
        markers = getattr(self, 'markers', None)
        if markers is not None:
            markers.close()
        diagnostics = getattr(self, 'diagnostics', None)
        if diagnostics is not None:
            diagnostics.log_summary()
        follower = getattr(self, 'follower', None)
        if follower is not None:
            follower.close()
        for name in ('solvers', 'stream_solvers'):
            solvers = getattr(self, name, None)
            if solvers is not None:
                solvers.close()
        super().destroy_node()
