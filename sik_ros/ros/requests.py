"""The handlers of sik_node's services: each request to its service module, its answer's markers.

:class:`RequestHandlers` is a part of :class:`~sik_ros.ros.node.SikNode`: it reads the node's
served arm, solvers, parameters, guard, joint states and markers, and hands each request to
:mod:`~sik_ros.ros.ik_service`, :mod:`~sik_ros.ros.batch_service` or
:mod:`~sik_ros.ros.path_service` through the node's :class:`~sik_ros.ros.guard.RequestGuard`.
The markers of an answer are handed over once it is on its way
(:func:`~sik_ros.ros.executor.after_answer`).
"""

from functools import partial
from typing import Optional

import numpy as np
from sensor_msgs.msg import JointState
from std_msgs.msg import Header

from sik_interfaces.srv import SolveIK, SolveIKBatch, SolvePath
from sik_ros.errors import SikError
from sik_ros.ros import conversions as conv
from sik_ros.ros.batch_service import solve_batch_request
from sik_ros.ros.executor import after_answer
from sik_ros.ros.ik_service import fill_answer, solve_request
from sik_ros.ros.path_service import solve_path_request


class RequestHandlers:
    """sik_node's service callbacks and the helpers they share (a part of ``SikNode``)."""

    def _header(self) -> Header:
        arm = self.arm
        return Header(stamp=self.get_clock().now().to_msg(),
                      frame_id=arm.base_frame if arm is not None else '')

    def state_seed(self) -> Optional[np.ndarray]:
        """Return the latest ``joint_states`` as a seed (clipped to the limits), or None."""
        return self.seed_from_state(self.joint_states.latest()[0])

    def seed_from_state(self, msg: Optional[JointState]) -> Optional[np.ndarray]:
        """A ``joint_states`` message as a seed (clipped to the limits), or None if unusable."""
        if msg is None:
            return None
        try:
            q = conv.seed_from_joint_state(msg, self.arm.joint_names, strict=False)
        except SikError as exc:
            self.get_logger().warning(f'joint_states not used as a seed: {exc}',
                                      throttle_duration_sec=5.0)
            return None
        if q is None or len(q) != len(self.arm.joint_names) or not np.all(np.isfinite(q)):
            return None
        return np.clip(q, self._ik.robot.lower, self._ik.robot.upper)

    def _fill_ik(self, request: SolveIK.Request, response, header: Header):
        """Solve a SolveIK request into ``response`` (its solutions); the code and message."""
        answer = solve_request(self.solvers, self.arm, request, self._params, self.state_seed)
        fill_answer(response, answer, self.arm, header)
        if self.markers.want():
            after_answer(partial(self.markers.solutions, self._ik.robot.chain,
                                 answer.result.solutions, header, answer.position,
                                 answer.orientation))
        return answer.code, answer.message

    def _on_solve_ik(self, request: SolveIK.Request, response: SolveIK.Response
                     ) -> SolveIK.Response:
        header = self._header()
        return self.guard.answer('solve_ik', response,
                                 lambda r: self._fill_ik(request, r, header))

    def _fill_batch(self, request: SolveIKBatch.Request, response: SolveIKBatch.Response,
                    header: Header):
        """Solve a SolveIKBatch request into ``response`` (its results); the code and message."""
        ik, solvers, arm = self._ik, self.solvers, self.arm
        if ik is None or solvers is None or arm is None:
            return SolveIK.Response.TIMEOUT, 'sik_node has no bundle loaded'
        code, message, results = solve_batch_request(
            solvers, arm, request, self._params, self.state_seed, ik.check_seed, header,
            self.give_way, self.guard.refusal)
        response.results = results
        return code, message

    def _on_solve_ik_batch(self, request: SolveIKBatch.Request,
                           response: SolveIKBatch.Response) -> SolveIKBatch.Response:
        header = self._header()
        return self.guard.answer('solve_ik_batch', response,
                                 lambda r: self._fill_batch(request, r, header))

    def _fill_path(self, request: SolvePath.Request, response: SolvePath.Response):
        header = self._header()
        code, message, result, trajectories, metrics = solve_path_request(
            self.solvers, self.arm, request, self._params, self._ik.robot.velocity_limits,
            header)
        response.fraction = float(result.fraction)
        response.trajectories, response.metrics = trajectories, metrics
        if result.paths and self.markers.want():
            after_answer(partial(self.markers.path, self._ik.robot.chain, result, header))
        return code, message

    def _on_solve_path(self, request: SolvePath.Request, response: SolvePath.Response
                       ) -> SolvePath.Response:
        return self.guard.answer('solve_path', response,
                                 lambda r: self._fill_path(request, r))
