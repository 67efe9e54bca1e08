"""The end-to-end tests' harness: a node on an isolated graph, and calls that resend.

Starting and stopping the node is :mod:`sik_ros.ros.launch` (the demo and the benchmarks use it
too); request builders are in :mod:`sik_ros.ros.client`. :func:`call` sends a request from the
test's own node and resends it when no answer comes within one attempt, as
:class:`sik_ros.ros.client.SolveIKClient` does: Fast DDS may drop the first replies to a new
client (see that module).
"""

import time
from typing import Optional

import rclpy
from rclpy.node import Node

from sik_ros.ros.client import box, pose_request, SolveIKClient
from sik_ros.ros.launch import (bundle_goals, launch_node, NODE, params_file, ros_env,
                                stop_node, wait_for_service)

__all__ = ['NODE', 'SolveIKClient', 'box', 'bundle_goals', 'call', 'launch_node', 'params_file',
           'pose_request', 'ros_env', 'stop_node', 'wait_for_service']


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
