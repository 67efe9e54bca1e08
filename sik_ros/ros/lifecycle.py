"""sik_node as a managed node (``-p lifecycle:=true``): rclpy's LifecycleNode over SikNode.

It starts unconfigured, with its services up but refusing. ``configure`` loads the bundle and
warms up the solvers; ``activate`` starts answering; ``deactivate`` makes ``~/solve_ik``,
``~/solve_path`` and ``~/goal`` answer TIMEOUT with a message naming the state (never a hang);
``cleanup`` stops the solvers and frees the models; ``shutdown`` frees them and ends the node's
process (exit 0). A configure that fails (a missing or mismatched bundle, a solver process
that cannot start) reports failure and leaves the node unconfigured, to be configured again.
The standard services are lifecycle_msgs' ``~/change_state``, ``~/get_state``,
``~/get_available_states`` and ``~/get_available_transitions``.
"""

import time
from typing import Optional, Tuple

from rclpy.lifecycle import LifecycleNodeMixin, LifecycleState, TransitionCallbackReturn
from rclpy.node import Node

from sik_interfaces.srv import SolveIK
from sik_ros.errors import SikError
from sik_ros.ros.node import NODE_NAME, SikNode, WORKERS

R = SolveIK.Response


class ManagedSikNode(LifecycleNodeMixin, SikNode):
    """sik_node driven through the ROS 2 lifecycle."""

    def __init__(self, workers: int = WORKERS, **kwargs):
        """Declare the parameters and create the interfaces; nothing is loaded yet."""
        self._active = False
        #: set once the shutdown transition is done: the process exits
        self.finished = False
        SikNode.__init__(self, workers, managed=True, **kwargs)
        LifecycleNodeMixin.__init__(self, enable_communication_interface=True)
        self.guard.refusals.insert(0, self._inactive_refusal)
        self.get_logger().info('managed node: unconfigured (configure and activate it '
                               'through ~/change_state)')

    @property
    def managed_state(self) -> str:
        """The lifecycle state's label (unconfigured, inactive, active, finalized, ...)."""
        return self._state_machine.current_state[1]

    def _inactive_refusal(self) -> Optional[Tuple[int, str]]:
        if self._active:
            return None
        return R.TIMEOUT, (f'sik_node is {self.managed_state} (a managed node): it answers '
                           f'only while active')

    def _drain(self) -> None:
        """Wait (up to shutdown_grace) for requests that came in while active."""
        deadline = time.monotonic() + self.shutdown_grace
        while self.in_flight and time.monotonic() < deadline:
            time.sleep(0.01)

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Load the bundle and warm up the solvers; FAILURE (still unconfigured) if they fail."""
        try:
            self.start()
        except SikError as exc:
            self.stop()
            self.get_logger().error(f'configure failed: {" ".join(str(exc).split())}')
            return TransitionCallbackReturn.FAILURE
        return super().on_configure(state)

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Start answering."""
        self._active = True
        self.get_logger().info('active: answering requests')
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop answering (requests get TIMEOUT and the state)."""
        self._active = False
        self._drain()
        self.get_logger().info('inactive: refusing requests')
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop the solvers and free the models."""
        self._active = False
        self._drain()
        self.stop()
        self.get_logger().info('unconfigured: bundle released')
        return super().on_cleanup(state)

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Free everything and let the process exit."""
        self._active = False
        self._drain()
        self.stop()
        self.finished = True
        self.get_logger().info('finalized: exiting')
        return super().on_shutdown(state)

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """A transition raised: free everything and go back to unconfigured."""
        self._active = False
        self.stop()
        self.get_logger().error(f'error while {state.label}: back to unconfigured')
        return TransitionCallbackReturn.SUCCESS


def lifecycle_requested(**kwargs) -> bool:
    """The ``lifecycle`` parameter given at start-up (``-p``, a params file), default false.

    Read by a short-lived node of the same name, which sees the same parameter overrides.
    """
    probe = Node(NODE_NAME, automatically_declare_parameters_from_overrides=True,
                 start_parameter_services=False, enable_rosout=False, **kwargs)
    try:
        if not probe.has_parameter('lifecycle'):
            return False
        return probe.get_parameter('lifecycle').value is True
    finally:
        probe.destroy_node()


def make_node(**kwargs) -> SikNode:
    """A :class:`ManagedSikNode` when ``lifecycle`` is true, else a :class:`SikNode`."""
    cls = ManagedSikNode if lifecycle_requested(**kwargs) else SikNode
    return cls(**kwargs)
