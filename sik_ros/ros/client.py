"""A blocking Python client of ``~/solve_ik`` that keeps latency low.

``rclpy.spin_until_future_complete`` rebuilds the executor's wait set on every call; spinning
one executor in a background thread and waiting on each future with a
:class:`threading.Event` costs a fraction of that (docs/benchmarks.md, the client loops). This
module does the latter::

    with SolveIKClient() as client:          # after rclpy.init()
        client.wait_for_service(10.0)
        answer = client.call(demo.pose_request([0.4, 0.1, 0.5]))

It is safe to call from several threads at once. :func:`pose_request` and :func:`batch_request`
build ``SolveIK`` and ``SolveIKBatch`` requests (``SolveIKClient('/sik_node/solve_ik_batch',
srv_type=SolveIKBatch)`` calls the latter).

Fast DDS matches a new client's request writer with the server's reader and the server's reply
writer with the client's reader separately (service discovery, rmw_fastrtps on Jazzy): for a
short while after a client appears, the server can take a request while its reply has no
matched reader yet and is dropped, so a client's first calls may never be answered although
the server handled them. :meth:`SolveIKClient.call` therefore waits until the service is
matched, and resends a call whose answer does not come within ``attempt`` seconds, all within
the caller's ``timeout``; IK requests have no side effects, so a resend is harmless.
"""

import threading
import time
from typing import Optional, Sequence

from geometry_msgs.msg import Pose
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from shape_msgs.msg import SolidPrimitive

from sik_interfaces.srv import SolveIK, SolveIKBatch

SERVICE = '/sik_node/solve_ik'


class SolveIKClient:
    """A node with a service client (``SolveIK`` by default), spun by its own thread."""

    def __init__(self, service: str = SERVICE, node_name: str = 'sik_client',
                 context: Optional[Context] = None, srv_type=SolveIK):
        """Create the node and start spinning it (rclpy must be initialised).

        Args:
            service: the service's name.
            node_name: the client node's name.
            context: the rclpy context (default: the global one).
            srv_type: the service type (``SolveIK``, ``SolvePath``, ...).
        """
        self.node = rclpy.create_node(node_name, context=context)
        self.client = self.node.create_client(srv_type, service)
        self._executor = SingleThreadedExecutor(context=context)
        self._executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, name=f'{node_name}_spin',
                                        daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        try:
            self._executor.spin()
        except Exception:  # shutdown of the context or the executor ends the thread
            pass

    def wait_for_service(self, timeout: float = 10.0) -> bool:
        """Whether the service appeared within ``timeout`` seconds."""
        return self.client.wait_for_service(timeout_sec=timeout)

    def call(self, request, timeout: float = 10.0, attempt: Optional[float] = None):
        """Send a request and wait for its answer [s]; None if none came in ``timeout``.

        Args:
            request: the request.
            timeout: the whole call's budget [s].
            attempt: how long one try waits before the request is sent again [s]; default:
                :func:`attempt_seconds`.
        """
        deadline = time.monotonic() + timeout
        if not self.client.service_is_ready() and not self.client.wait_for_service(
                timeout_sec=timeout):
            return None
        if attempt is None:
            attempt = attempt_seconds(request)
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            done = threading.Event()
            future = self.client.call_async(request)
            future.add_done_callback(lambda _: done.set())
            if done.wait(min(attempt, left)):
                return future.result()
            self.client.remove_pending_request(future)

    def close(self) -> None:
        """Stop the spinning thread and destroy the node."""
        self._executor.shutdown(timeout_sec=1.0)
        self._thread.join(timeout=2.0)
        self.node.destroy_node()

    def __enter__(self) -> 'SolveIKClient':
        """Use as a context manager: closed on exit."""
        return self

    def __exit__(self, *exc) -> None:
        """Close the client."""
        self.close()


def attempt_seconds(request) -> float:
    """How long a call waits for its answer before it sends the request again [s].

    The request's own timeout plus a second, or 2 s when it gives none or has no ``timeout``
    field; a ``SolveIKBatch`` request's timeout is per target, so it counts once per target.
    """
    budget = getattr(request, 'timeout', None)  # a SolveIK, SolveIKBatch or SolvePath request's
    given = 0.0 if budget is None else budget.sec + budget.nanosec * 1e-9
    targets = max(1, len(getattr(request, 'targets', ())))
    return given * targets + 1.0 if given > 0 else 2.0 * targets


def pose_request(position: Sequence[float], orientation: Optional[Sequence[float]] = None,
                 max_solutions: int = 0, frame_id: str = '') -> SolveIK.Request:
    """Build a SolveIK request: a position goal, or a pose goal with a quaternion x y z w."""
    req = SolveIK.Request(max_solutions=max_solutions)
    req.target.header.frame_id = frame_id
    p = req.target.pose.position
    p.x, p.y, p.z = (float(v) for v in position)
    if orientation is not None:
        o = req.target.pose.orientation
        o.x, o.y, o.z, o.w = (float(v) for v in orientation)
        req.use_orientation = True
    return req


def batch_request(positions: Sequence[Sequence[float]],
                  orientations: Optional[Sequence[Sequence[float]]] = None,
                  max_solutions: int = 0, frame_id: str = '') -> SolveIKBatch.Request:
    """Build a SolveIKBatch request: position goals, or pose goals with quaternions x y z w."""
    singles = [pose_request(p, None if orientations is None else orientations[i], 0, frame_id)
               for i, p in enumerate(positions)]
    return SolveIKBatch.Request(targets=[s.target for s in singles],
                                use_orientation=orientations is not None,
                                max_solutions=max_solutions)


def box(center: Sequence[float], size: Sequence[float]):
    """Make a box obstacle (SolidPrimitive, Pose) centred at ``center`` with sides ``size`` [m]."""
    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in center)
    return SolidPrimitive(type=SolidPrimitive.BOX, dimensions=[float(v) for v in size]), pose
