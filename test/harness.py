"""The end-to-end tests' harness: a node on an isolated graph, and calls that resend.

Starting and stopping the node is :mod:`sik_ros.ros.launch` (the demo and the benchmarks use it
too); request builders are in :mod:`sik_ros.ros.client`. :func:`call` sends a request from the
test's own node and resends it when no answer comes within one attempt, as
:class:`sik_ros.ros.client.SolveIKClient` does: Fast DDS may drop the first replies to a new
client (see that module).
"""

import contextlib
import subprocess
import time
from typing import Dict, Iterator, Optional, Sequence, Tuple

import pytest
import rclpy
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from sik_ros.ros.client import box, pose_request, SolveIKClient
from sik_ros.ros.launch import (bundle_goals, launch_node, NODE, params_file, ros_env,
                                stop_node, wait_for_service)

__all__ = ['NODE', 'SolveIKClient', 'box', 'bundle_goals', 'call', 'launch_node',
           'node_with_clients', 'params_file', 'pose_request', 'ros_env', 'stop_node',
           'wait_for_service']


@contextlib.contextmanager
def node_with_clients(tmp_path_factory, name: str, clients: Dict[str, Tuple[type, str]],
                      params: Sequence[str] = ()) -> Iterator[Node]:
    """A sik_node with the bundled Panda, and a client node ``name`` once its services are up.

    ``clients``: attribute -> (service type, service name); each client is set on the node as
    that attribute. The test fails with the node's log when a service does not come up.
    """
    env = ros_env()
    log_path = tmp_path_factory.mktemp('sik_node') / 'node.log'
    with open(log_path, 'wb') as log:
        proc = launch_node(None, list(params), env=env, stdout=log, stderr=subprocess.STDOUT)
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(name)
    for attr, (srv_type, service) in clients.items():
        setattr(node, attr, node.create_client(srv_type, service))
    up = all(wait_for_service(node, getattr(node, attr), proc, 90.0) for attr in clients)
    try:
        if up:
            yield node
    finally:
        node.destroy_node()
        rclpy.shutdown()
        stop_node(proc)
    if not up:
        names = ', '.join(service for _, service in clients.values())
        pytest.fail(f'sik_node did not offer {names}:\n{log_path.read_text()}')


def call(node: Node, client, request, timeout: float = 10.0,
         attempt: Optional[float] = None):
    """Send a request from ``node`` and wait for its answer [s], resending; None if none came.

    Args:
        node: the test's node (spun here while waiting).
        client: a client of ``node``.
        request: the request.
        timeout: the whole call's budget [s].
        attempt: how long one try waits before the request is sent again [s]; default: the
            request's own timeout plus a second (or 2 s when it has none).
    """
    deadline = time.monotonic() + timeout
    if attempt is None:
        given = getattr(request, 'timeout', None)
        seconds = 0.0 if given is None else given.sec + given.nanosec * 1e-9
        attempt = seconds + 1.0 if seconds > 0 else 2.0
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            return None
        future = client.call_async(request)
        rclpy.spin_until_future_complete(node, future, timeout_sec=min(attempt, left))
        if future.done():
            return future.result()
        client.remove_pending_request(future)
