"""sik_node: the ROS 2 node over :class:`~sik_ros.solver.SelectiveIK`.

Service ``~/solve_ik`` (``sik_interfaces/srv/SolveIK``), topics ``~/goal`` -> ``~/solutions``,
``joint_states`` (optional seed) and ``~/markers`` (RViz). Run it with
``sik_node --ros-args --params-file config/panda.yaml``. See docs/interfaces.md, section 4.

Concurrency: a :class:`MultiThreadedExecutor` runs the service and goal callbacks in a reentrant
callback group. Each callback hands its solve to one of ``solver_processes`` solver processes
(:class:`~sik_ros.solver_pool.SolverPool`: parallel beyond the GIL, each with its own
:class:`SelectiveIK`), or, with ``solver_processes: 0``, borrows a solver of its own (a
:meth:`SelectiveIK.clone`, with its own Pinocchio and coal data) from a pool of clones, so
parallel requests never share mutable state.
"""

from contextlib import contextmanager
from dataclasses import fields, replace
import queue
import threading
import traceback
from typing import Iterator, List, Optional, Tuple

from geometry_msgs.msg import PoseStamped
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.exceptions import InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, qos_profile_sensor_data, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Header, String
from visualization_msgs.msg import MarkerArray

from sik_interfaces.msg import IKSolution, IKSolutionArray
from sik_interfaces.srv import SolveIK, SolvePath
from sik_ros.errors import SikError
from sik_ros.robots import chain_differences
from sik_ros.ros import conversions as conv
from sik_ros.ros.params import declarations, NodeParams, validate
from sik_ros.ros.path_service import handle_path
from sik_ros.solver import IKResult, SelectiveIK
from sik_ros.solver_pool import single_threaded, SolverCrashed, SolverPool, SolverTimeout

NODE_NAME = 'sik_node'
#: Goals ``~/goal`` keeps while the solvers are busy (KEEP_LAST): a burst of more loses the
#: oldest, as any KEEP_LAST subscription does; a client that needs every answer calls the
#: service.
GOAL_QUEUE = 100

#: Depth of the services' request queues. ROS 2's default for services keeps the last 10
#: requests: with more clients waiting than that while every executor thread is busy, Fast
#: DDS drops the oldest unread requests, and their clients wait for a resend (measured:
#: bench/soak.py, docs/benchmarks.md).
SERVICE_QUEUE = 256
#: Executor threads, and solver instances in the pool (one per thread).
WORKERS = 4
#: Longest time the main thread waits in the executor before it checks for signals [s].
SPIN_PERIOD = 0.1
Response = SolveIK.Response


class StartupError(SikError):
    """The node cannot start: bad parameters or an unusable bundle."""


class SikNode(Node):
    """The IK node: loads a bundle, answers ``~/solve_ik`` and ``~/goal``, publishes markers."""

    def __init__(self, workers: int = WORKERS, **kwargs):
        """Declare the parameters, load the bundle and create the ROS interfaces.

        Args:
            workers: solver instances (as many as the executor has threads).
            **kwargs: passed to :class:`rclpy.node.Node` (e.g. ``parameter_overrides``).

        Raises:
            StartupError: bad parameter values, or a missing, corrupt or mismatched bundle.
        """
        super().__init__(NODE_NAME, **kwargs)
        single_threaded()
        self.workers = workers
        self._declare_parameters()
        self._params = self._read_parameters()
        reason = validate(self._params)
        if reason is not None:
            raise StartupError(f'bad parameters: {reason}')
        self._ik = self._load(self._params)
        self.shutdown_grace = self._params.shutdown_grace
        #: why requests are refused: the robot_description topic's chain differs from the bundle's
        self._mismatch: Optional[str] = None
        #: set on SIGINT/SIGTERM: new requests are answered TIMEOUT, nothing is published
        self.closing = False
        self._in_flight = 0
        self._in_flight_lock = threading.Lock()
        self._pool: 'queue.LifoQueue[SelectiveIK]' = queue.LifoQueue()
        self._processes: Optional[SolverPool] = None
        if self._params.solver_processes > 0:
            try:
                self._processes = SolverPool(self._ik.bundle, self._ik.config,
                                             self._params.solver_processes)
            except SikError as exc:
                raise StartupError(f'cannot start the solver processes: {exc}') from exc
        else:
            took = 0.0
            for _ in range(workers):
                ik = self._ik.clone()
                took += ik.warm_up()
                self._pool.put(ik)
            self.get_logger().info(f'{workers} solvers warmed up in {took:.2f} s')
        self._joint_state: Optional[JointState] = None
        self._joint_state_sub = None
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)

        group = ReentrantCallbackGroup()
        self._solutions_pub = self.create_publisher(IKSolutionArray, '~/solutions', 10)
        self._markers_pub = self.create_publisher(MarkerArray, '~/markers', 5)
        requests = QoSProfile(depth=SERVICE_QUEUE, reliability=ReliabilityPolicy.RELIABLE)
        self.create_service(SolveIK, '~/solve_ik', self._on_solve_ik, qos_profile=requests,
                            callback_group=group)
        self.create_service(SolvePath, '~/solve_path', self._on_solve_path,
                            qos_profile=requests, callback_group=group)
        self.create_subscription(PoseStamped, '~/goal', self._on_goal, GOAL_QUEUE,
                                 callback_group=group)
        self._update_joint_state_subscription()
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                             reliability=ReliabilityPolicy.RELIABLE)
        self.create_subscription(String, 'robot_description', self._on_robot_description,
                                 latched, callback_group=group)
        self.get_logger().info(
            f'ready: bundle {self._ik.bundle} ({", ".join(self._ik.goals)} goals, '
            f'{len(self._ik.joint_names)} joints {self._ik.robot.base_frame} -> '
            f'{self._ik.robot.tip_frame}), {workers} executor threads, '
            f'{self._params.solver_processes} solver processes')

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
        self._update_joint_state_subscription()
        self.get_logger().info('parameters set: ' + ', '.join(
            f'{c.name}={c.value!r}' for c in changes))

    def _update_joint_state_subscription(self) -> None:
        want = self._params.use_joint_states
        if want and self._joint_state_sub is None:
            self._joint_state_sub = self.create_subscription(
                JointState, 'joint_states', self._on_joint_state, qos_profile_sensor_data)
        elif not want and self._joint_state_sub is not None:
            self.destroy_subscription(self._joint_state_sub)
            self._joint_state_sub = None
            self._joint_state = None

    # -- solvers ---------------------------------------------------------------------------------

    def _load(self, p: NodeParams) -> SelectiveIK:
        bundle = p.model_dir or p.robot
        try:
            ik = SelectiveIK.load(bundle)
        except SikError as exc:
            raise StartupError(f'cannot load the IK bundle {bundle!r}: {exc}') from exc
        robot = ik.robot
        for name, value, actual in (('base_frame', p.base_frame, robot.base_frame),
                                    ('tip_frame', p.tip_frame, robot.tip_frame)):
            if value and value != actual:
                raise StartupError(f'parameter {name} is {value!r} but bundle {bundle!r} was '
                                   f'made for {actual!r}')
        if p.robot_description:
            reason = self._differences(robot, p.robot_description)
            if reason:
                raise StartupError(f'bundle {bundle!r} does not fit the robot_description: '
                                   f'{reason}')
        return ik.with_config(**self._solver_settings(p))

    @staticmethod
    def _differences(robot, urdf: str) -> str:
        """How a URDF's chain differs from the bundle's robot ('' if it does not)."""
        try:
            return '; '.join(chain_differences(robot, urdf))
        except SikError as exc:
            return str(exc)

    def _on_robot_description(self, msg: String) -> None:
        reason = self._differences(self._ik.robot, msg.data)
        self._mismatch = (f'the bundle {self._ik.bundle} does not fit the robot_description '
                          f'topic: {reason}') if reason else None
        if reason:
            self.get_logger().error(f'{self._mismatch}; refusing requests')
        else:
            self.get_logger().info('robot_description matches the bundle\'s chain')

    @staticmethod
    def _solver_settings(p: NodeParams) -> dict:
        return {'position_tolerance': p.position_tolerance,
                'orientation_tolerance': p.orientation_tolerance,
                'max_solutions_cap': p.max_solutions_cap, 'max_obstacles': p.max_obstacles,
                'max_waypoints': p.max_waypoints}

    @contextmanager
    def _solver(self, p: NodeParams) -> Iterator[SelectiveIK]:
        """Borrow a solver from the pool, with the settings of ``p``."""
        ik = self._pool.get()
        try:
            settings = self._solver_settings(p)
            if any(getattr(ik.config, k) != v for k, v in settings.items()):
                ik.configure(**settings)  # keeps its Pinocchio and coal data
            yield ik
        finally:
            self._pool.put(ik)

    # -- requests --------------------------------------------------------------------------------

    def _header(self, p: NodeParams) -> Header:
        return Header(stamp=self.get_clock().now().to_msg(), frame_id=self._ik.robot.base_frame)

    def _state_seed(self) -> Optional[np.ndarray]:
        """Return the latest ``joint_states`` as a seed (clipped to the limits), or None."""
        msg = self._joint_state
        if msg is None:
            return None
        try:
            q = conv.seed_from_joint_state(msg, self._ik.joint_names, strict=False)
        except SikError as exc:
            self.get_logger().warning(f'joint_states not used as a seed: {exc}',
                                      throttle_duration_sec=5.0)
            return None
        if q is None or len(q) != len(self._ik.joint_names) or not np.all(np.isfinite(q)):
            return None
        return np.clip(q, self._ik.robot.lower, self._ik.robot.upper)

    def _solve(self, request: SolveIK.Request, p: NodeParams
               ) -> Tuple[int, str, Optional[IKResult]]:
        """Error code, message and (when the goal was valid) the library's result."""
        if self._mismatch is not None:
            return Response.ROBOT_MISMATCH, self._mismatch, None
        frame = request.target.header.frame_id.lstrip('/')
        base = self._ik.robot.base_frame
        if frame not in ('', base):
            return (Response.INVALID_FRAME,
                    f'target frame_id {request.target.header.frame_id!r} is not the base frame '
                    f'{base!r} (or empty); sik_node does not transform frames', None)
        num, note = conv.solution_count(request.max_solutions, p.num_solutions,
                                        p.max_solutions_cap)
        try:
            position, orientation = conv.goal_from_pose(request.target.pose,
                                                        request.use_orientation)
            seed = conv.seed_from_joint_state(request.seed, self._ik.joint_names)
            if seed is None and p.use_joint_states:
                seed = self._state_seed()
            obstacles = conv.obstacles_from_msgs(request.obstacles, request.obstacle_poses)
            timeout = conv.seconds_from_duration(request.timeout) or p.timeout
            if self._processes is not None:
                result = self._processes.solve(
                    self._solver_settings(p), position, orientation, num, seed=seed,
                    obstacles=obstacles, refine=p.refine, timeout=timeout)
            else:
                with self._solver(p) as ik:
                    result = ik.solve(position, orientation, num, seed=seed,
                                      obstacles=obstacles, refine=p.refine, timeout=timeout)
        except SolverTimeout as exc:
            self.get_logger().warning(str(exc))
            return Response.TIMEOUT, str(exc), None
        except SolverCrashed as exc:
            self.get_logger().error(str(exc))
            return Response.INTERNAL_ERROR, f'internal error: {exc}', None
        except SikError as exc:
            return conv.error_code_for(exc), str(exc), None
        code, text = conv.result_code(result, bool(obstacles), timeout)
        return code, '; '.join(t for t in (text, note) if t), result

    def _answer(self, request: SolveIK.Request, where: str
                ) -> Tuple[int, str, List[IKSolution], Header]:
        """Error code, message, IKSolutions and header of the answer to a request; never raises."""
        p = self._params
        header = self._header(p)
        if self.closing:
            return Response.TIMEOUT, 'sik_node is shutting down', [], header
        with self._counted():
            return self._answer_counted(request, where, p, header)

    @property
    def params(self) -> NodeParams:
        """The parameters in force."""
        return self._params

    @property
    def ik(self) -> SelectiveIK:
        """The loaded solver (the one the clones and processes are made from)."""
        return self._ik

    @property
    def mismatch(self) -> Optional[str]:
        """Why requests are refused (the robot_description differs), or None."""
        return self._mismatch

    @property
    def markers_pub(self):
        """The ``~/markers`` publisher."""
        return self._markers_pub

    @property
    def in_flight(self) -> int:
        """Requests being answered now."""
        return self._in_flight

    def _answer_counted(self, request: SolveIK.Request, where: str, p: NodeParams,
                        header: Header) -> Tuple[int, str, List[IKSolution], Header]:
        try:
            code, message, result = self._solve(request, p)
            solutions = [] if result is None else [
                conv.solution_to_msg(s, self._ik.joint_names, header) for s in result.solutions]
            if result is not None and p.publish_markers and not self.closing \
                    and self._markers_pub.get_subscription_count() > 0:
                position, orientation = conv.goal_from_pose(request.target.pose,
                                                            request.use_orientation)
                self._markers_pub.publish(conv.posture_markers(
                    self._ik.robot.chain, result.solutions, header, position, orientation))
        except Exception as exc:  # the node answers every request, whatever fails
            self.get_logger().error(f'{where}: unexpected {type(exc).__name__}: {exc}\n'
                                    f'{traceback.format_exc()}')
            return (Response.INTERNAL_ERROR, f'internal error: {type(exc).__name__}: {exc}',
                    [], header)
        if code != Response.SUCCESS:
            self.get_logger().debug(f'{where}: {conv.ERROR_NAMES.get(code, code)}: {message}')
        return code, message, solutions, header

    def _on_solve_ik(self, request: SolveIK.Request, response: SolveIK.Response
                     ) -> SolveIK.Response:
        response.error_code, response.message, response.solutions, _ = self._answer(
            request, 'solve_ik')
        return response

    def _on_solve_path(self, request: SolvePath.Request, response: SolvePath.Response
                       ) -> SolvePath.Response:
        with self._counted():
            return handle_path(self, request, response)

    @contextmanager
    def _counted(self) -> Iterator[None]:
        """Count a request as in flight while it is answered."""
        with self._in_flight_lock:
            self._in_flight += 1
        try:
            yield
        finally:
            with self._in_flight_lock:
                self._in_flight -= 1

    @contextmanager
    def path_solver(self, p: NodeParams) -> Iterator[SelectiveIK]:
        """A solver for a path: from the pool of clones, or (solver processes) the node's own."""
        if self._processes is None:
            with self._solver(p) as ik:
                yield ik
        else:
            yield self._ik  # its own lock serialises path requests in this mode

    def _on_goal(self, msg: PoseStamped) -> None:
        request = SolveIK.Request(target=msg, use_orientation=self._params.goal_use_orientation)
        code, message, solutions, header = self._answer(request, 'goal')
        if not self.closing:
            self._solutions_pub.publish(conv.solution_array(header, code, message, solutions))

    def _on_joint_state(self, msg: JointState) -> None:
        self._joint_state = msg

    def destroy_node(self) -> None:
        """Stop the solver processes, then destroy the node."""
        if getattr(self, '_processes', None) is not None:
            self._processes.close()
        super().destroy_node()


def main(args: Optional[List[str]] = None) -> int:
    """Run sik_node (see :func:`sik_ros.ros.run.main`)."""
    from sik_ros.ros.run import main as run
    return run(args)


if __name__ == '__main__':
    raise SystemExit(main())
