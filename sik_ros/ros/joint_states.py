"""The arm's latest ``joint_states``, taken when a request needs it: no executor turn per message.

A robot publishes ``joint_states`` at 100-1000 Hz and sik_node needs only the newest message,
when a request without a seed or a stream goal is solved. :class:`JointStateTap` subscribes on a
node of its own that no executor spins, and :meth:`JointStateTap.latest` takes every message
queued since the last call (the subscription keeps the last few, as sensor data QoS does) and
keeps the newest with the time it was received.
"""

import threading
import time
from typing import Optional, Tuple

from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import JointState

from sik_ros.ros.side_node import side_node, take_newest


class JointStateTap:
    """The newest ``joint_states`` message, read on demand; safe from every thread."""

    def __init__(self, node) -> None:
        """Make the tap's node (not subscribed until :meth:`enable`).

        Args:
            node: the node whose ``joint_states`` topic (as it resolves it) is read.
        """
        self._topic = node.resolve_topic_name('joint_states')
        self._node = side_node(node, 'joint_states')
        self._sub = None
        self._lock = threading.Lock()
        self._msg: Optional[JointState] = None
        self._received: Optional[float] = None

    def enable(self, on: bool) -> None:
        """Subscribe (``on``) or unsubscribe and forget the last message."""
        with self._lock:
            if on and self._sub is None:
                self._sub = self._node.create_subscription(
                    JointState, self._topic, lambda _: None, qos_profile_sensor_data)
            elif not on and self._sub is not None:
                self._node.destroy_subscription(self._sub)
                self._sub, self._msg, self._received = None, None, None

    def latest(self) -> Tuple[Optional[JointState], Optional[float]]:
        """The newest message and when it was received (``time.time()`` [s]); Nones for none."""
        with self._lock:
            sub = self._sub
            if sub is None:
                return None, None
            msg, info, _ = take_newest(sub, JointState)
            if msg is not None:
                stamp = info.get('received_timestamp') if isinstance(info, dict) else None
                self._msg = msg
                self._received = stamp * 1e-9 if stamp else time.time()
            return self._msg, self._received

    def close(self) -> None:
        """Destroy the tap's node."""
        with self._lock:
            self._sub = None
        self._node.destroy_node()
