"""An empty ROS 2 service served as sik_node serves ``~/solve_ik``: the floor of a round trip.

``std_srvs/Trigger`` at ``/sik_bench_empty/trigger``, answered at once, by a node spun as
``sik_node`` is (:mod:`sik_ros.ros.run`): a :class:`~sik_ros.ros.executor.SlottedExecutor`
with the node's executor threads, the service in a reentrant callback group with the node's
request queue depth. ``bench/service.py`` starts it as a process beside the node and calls both
from the same client, so what the node adds to rclpy's own cost of a call shows as a ratio
measured in one run.

Beside it, the floor of an answer of sik_node's size: ``sik_interfaces/SolveIK`` at
``/sik_bench_empty/message``, answering every request with the same 16 ranked solutions,
solved once at start by the bundled Panda and converted as the node converts them. It costs
what moving such an answer through rclpy costs (building, serialising and reading the
messages), without a solve.

Usage: ``python bench/empty_service.py`` (until SIGINT), on the ROS graph of its environment.
"""

from typing import Callable, List, Optional

import rclpy
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import ExternalShutdownException
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Header
from std_srvs.srv import Trigger

from sik_interfaces.srv import SolveIK
from sik_ros.ros.executor import SlottedExecutor
from sik_ros.ros.ik_service import Arm, solution_msgs
from sik_ros.ros.node import SERVICE_QUEUE, SPIN_PERIOD, WORKERS
from sik_ros.solver import SelectiveIK

NAME = 'sik_bench_empty'
SERVICE = f'/{NAME}/trigger'
MESSAGE_SERVICE = f'/{NAME}/message'
#: Solutions in the message service's answer (bench/service.py asks the node for as many).
SOLUTIONS = 16


def answer(request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
    """Answer at once."""
    response.success = True
    return response


def solutions_answer(node) -> Callable[[SolveIK.Request, SolveIK.Response], SolveIK.Response]:
    """A callback answering every request with the same :data:`SOLUTIONS` Panda solutions.

    Solved once, for the tip pose of the middle of the joint ranges, by the bundled models;
    converted to messages by the node's own code, for each answer (as the node does).
    """
    ik = SelectiveIK.load('panda')
    robot = ik.robot
    result = ik.solve(*ik.fk((robot.lower + robot.upper) / 2), num_solutions=SOLUTIONS)
    for s in result.solutions:
        s.posture_index  # noqa: B018 (encoded once here, not at each answer)
    arm = Arm(robot.base_frame, list(ik.joint_names))

    def respond(request: SolveIK.Request, response: SolveIK.Response) -> SolveIK.Response:
        header = Header(stamp=node.get_clock().now().to_msg(), frame_id=arm.base_frame)
        response.solutions = solution_msgs(result, arm, header)
        response.error_code = SolveIK.Response.SUCCESS
        return response

    return respond


def main(argv: Optional[List[str]] = None) -> int:
    """Serve the empty service until SIGINT."""
    rclpy.init(args=argv)
    node = rclpy.create_node(NAME)
    requests = QoSProfile(depth=SERVICE_QUEUE, reliability=ReliabilityPolicy.RELIABLE)
    group = ReentrantCallbackGroup()
    node.create_service(Trigger, '~/trigger', answer, qos_profile=requests,
                        callback_group=group)
    node.create_service(SolveIK, '~/message', solutions_answer(node), qos_profile=requests,
                        callback_group=group)
    executor = SlottedExecutor(WORKERS)
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
