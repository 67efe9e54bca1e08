"""``~/solve_path``: Cartesian paths as timed joint trajectories, and their RViz markers."""

import traceback
from typing import List, Tuple

import numpy as np
from std_msgs.msg import Header
from visualization_msgs.msg import Marker, MarkerArray

from sik_interfaces.srv import SolvePath
from sik_ros.chain import chain_forward
from sik_ros.errors import SikError
from sik_ros.ros import conversions as conv
from sik_ros.ros.trajectories import trajectory_msg, waypoints_from_msgs
from sik_ros.solver import PathResult, SelectiveIK, Solution

Response = SolvePath.Response
#: Postures of the best path drawn on ~/markers (evenly spaced along it).
DRAWN_POSTURES = 4


def path_markers(ik: SelectiveIK, result: PathResult, header: Header) -> MarkerArray:
    """The best path's tool trace (namespace ``path``) and a few of its postures."""
    best = result.paths[0]
    rows = np.unique(np.linspace(0, len(best.q) - 1, DRAWN_POSTURES).round().astype(int))
    sols = [Solution(best.q[i], float(best.position_errors[i]),
                     float(best.orientation_errors[i]), np.zeros(0, dtype=np.float32))
            for i in rows]
    markers = conv.posture_markers(ik.robot.chain, sols, header)
    tip, _ = chain_forward(ik.robot.chain, best.q)
    trace = Marker(header=header, ns='path', id=0, type=Marker.LINE_STRIP, action=Marker.ADD,
                   color=conv._color(conv.TARGET_COLOR), points=conv._points(tip))
    trace.pose.orientation.w = 1.0
    trace.scale.x = 0.005
    markers.markers.append(trace)
    return markers


def answer_path(ik: SelectiveIK, request: SolvePath.Request, timeout: float, header: Header
                ) -> Tuple[int, str, float, list, list, PathResult]:
    """Code, message, fraction, trajectories, metrics and result of a path request.

    Raises nothing for bad input: every :class:`SikError` becomes its code and message.
    """
    base = ik.robot.base_frame
    try:
        positions, quats, frames = waypoints_from_msgs(request.waypoints, request.use_orientation)
        wrong = [i for i, f in enumerate(frames) if f not in ('', base)]
        if wrong:
            return (Response.INVALID_FRAME, f'waypoint {wrong[0]} frame_id '
                    f'{frames[wrong[0]]!r} is not the base frame {base!r} (or empty)', 0.0,
                    [], [], None)
        scaling = request.velocity_scaling or 1.0
        if not 0.0 < scaling <= 1.0:
            return (Response.INVALID_GOAL, f'velocity_scaling must be in (0, 1]; got '
                    f'{request.velocity_scaling}', 0.0, [], [], None)
        seed = conv.seed_from_joint_state(request.seed, ik.joint_names)
        obstacles = conv.obstacles_from_msgs(request.obstacles, request.obstacle_poses)
        step = request.max_joint_step if request.max_joint_step != 0 else 0.3
        result = ik.solve_path(positions, quats, seed=seed, num_paths=request.max_paths or 4,
                               max_joint_step=step, obstacles=obstacles, timeout=timeout)
    except SikError as exc:
        return conv.error_code_for(exc), str(exc), 0.0, [], [], None
    trajectories: List = []
    metrics: List = []
    for path in result.paths:
        traj, m = trajectory_msg(path, ik.joint_names, ik.robot.velocity_limits, scaling, header)
        trajectories.append(traj)
        metrics.append(m)
    summary = (f'{len(result.paths)} paths through {len(positions)} waypoints, fraction '
               f'{result.fraction:.3f}, {result.elapsed * 1e3:.1f} ms')
    if result.success:
        code = Response.SUCCESS
    elif result.timed_out:
        code = Response.TIMEOUT
    else:
        code = Response.NO_SOLUTION
    text = summary if result.success else f'{result.message} ({summary})'
    return code, text, result.fraction, trajectories, metrics, result


def handle_path(node, request: SolvePath.Request, response: SolvePath.Response
                ) -> SolvePath.Response:
    """The node's answer to a ``~/solve_path`` request (never raises)."""
    p = node.params
    header = Header(stamp=node.get_clock().now().to_msg(), frame_id=node.ik.robot.base_frame)
    if node.closing:
        response.error_code, response.message = Response.TIMEOUT, 'sik_node is shutting down'
        return response
    if node.mismatch is not None:
        response.error_code, response.message = Response.ROBOT_MISMATCH, node.mismatch
        return response
    try:
        timeout = conv.seconds_from_duration(request.timeout) or p.path_timeout
        with node.path_solver(p) as ik:
            code, message, fraction, trajs, metrics, result = answer_path(
                ik, request, timeout, header)
        if result is not None and result.paths and p.publish_markers and not node.closing \
                and node.markers_pub.get_subscription_count() > 0:
            node.markers_pub.publish(path_markers(node.ik, result, header))
    except Exception as exc:  # the node answers every request, whatever fails
        node.get_logger().error(f'solve_path: unexpected {type(exc).__name__}: {exc}\n'
                                f'{traceback.format_exc()}')
        code, message, fraction, trajs, metrics = (
            Response.INTERNAL_ERROR, f'internal error: {type(exc).__name__}: {exc}', 0.0, [], [])
    response.error_code, response.message, response.fraction = code, message, fraction
    response.trajectories, response.metrics = trajs, metrics
    return response
