"""Subscriptions outside the node's executor: a node of their own, and their queue taken whole.

Both the ``~/goal`` stream and the ``joint_states`` tap need only the newest message of a busy
topic. Each subscribes on a side node (:func:`side_node`: same context and namespace, no
parameter services) that the node's executor does not spin, and takes what is queued in one go
(:func:`take_newest`) instead of one executor turn per message.
"""

from typing import Any, Optional, Tuple

import rclpy
from rclpy.exceptions import InvalidHandle


def side_node(node, suffix: str):
    """A node ``<node's name>_<suffix>`` beside ``node`` (same context and namespace)."""
    return rclpy.create_node(f'{node.get_name()}_{suffix}', namespace=node.get_namespace(),
                             context=node.context, start_parameter_services=False)


def take_newest(sub, msg_type) -> Tuple[Optional[Any], Optional[dict], int]:
    """Take every message queued on ``sub``: the newest, its message info and how many were taken.

    ``(None, None, 0)`` when none was queued or the subscription is being destroyed.
    """
    msg, info, count = None, None, 0
    try:
        with sub.handle:
            while True:
                taken = sub.handle.take_message(msg_type, False)
                if taken is None:
                    break
                (msg, info), count = taken, count + 1
    except InvalidHandle:  # destroyed while shutting down
        pass
    return msg, info, count
