"""An empty ROS 2 service served as sik_node serves ``~/solve_ik``: the floor of a round trip.

``std_srvs/Trigger`` at ``/sik_bench_empty/trigger``, answered at once, by a node spun as
``sik_node`` is (:mod:`sik_ros.ros.run`): a :class:`MultiThreadedExecutor` with the node's
executor threads, the service in a reentrant callback group with the node's request queue
depth. ``bench/service.py`` starts it as a process beside the node and calls both from the same
client, so what the node adds to rclpy's own cost of a call shows as a ratio measured in one
run.

Usage: ``python bench/empty_service.py`` (until SIGINT), on the ROS graph of its environment.
"""

from typing import List, Optional

import rclpy
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_srvs.srv import Trigger

from sik_ros.ros.node import SERVICE_QUEUE, SPIN_PERIOD, WORKERS

NAME = 'sik_bench_empty'
SERVICE = f'/{NAME}/trigger'


def answer(request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
    """Answer at once."""
    response.success = True
    return response


def main(argv: Optional[List[str]] = None) -> int:
    """Serve the empty service until SIGINT."""
    rclpy.init(args=argv)
    node = rclpy.create_node(NAME)
    requests = QoSProfile(depth=SERVICE_QUEUE, reliability=ReliabilityPolicy.RELIABLE)
    node.create_service(Trigger, '~/trigger', answer, qos_profile=requests,
                        callback_group=ReentrantCallbackGroup())
    executor = MultiThreadedExecutor(num_threads=WORKERS)
    executor.add_node(node)
    try:
        while rclpy.ok():
            executor.spin_once(timeout_sec=SPIN_PERIOD)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown(timeout_sec=0)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
