"""``~/solve_path``: Cartesian paths as timed joint trajectories, and their RViz markers."""

from typing import Tuple

import numpy as np
from std_msgs.msg import Header
from visualization_msgs.msg import Marker, MarkerArray

from sik_interfaces.srv import SolvePath
from sik_ros.errors import InvalidGoal
from sik_ros.kinematics.chain import chain_forward
from sik_ros.ros import conversions as conv
from sik_ros.ros.ik_service import Arm
from sik_ros.ros.params import NodeParams
from sik_ros.ros.trajectories import trajectory_msg, waypoints_from_msgs
from sik_ros.serving.solvers import Solver
from sik_ros.solver import PathResult, Solution
from sik_ros.solver.config import PATH_DEFAULTS

Response = SolvePath.Response
#: Postures of the best path drawn on ~/markers (evenly spaced along it).
DRAWN_POSTURES = 4


def path_markers(chain, result: PathResult, header: Header) -> MarkerArray:
    """The best path's tool trace (namespace ``path``) and a few of its postures."""
    best = result.paths[0]
    rows = np.unique(np.linspace(0, len(best.q) - 1, DRAWN_POSTURES).round().astype(int))
    sols = [Solution(q=best.q[i], position_error=float(best.position_errors[i]),
                     orientation_error=float(best.orientation_errors[i]),
                     posture_index=np.zeros(0, dtype=np.float32))
            for i in rows]
    markers = conv.posture_markers(chain, sols, header)
    tip, _ = chain_forward(chain, best.q)
    trace = Marker(header=header, ns='path', id=0, type=Marker.LINE_STRIP, action=Marker.ADD,
                   color=conv._color(conv.TARGET_COLOR), points=conv._points(tip))
    trace.pose.orientation.w = 1.0
    trace.scale.x = 0.005
    markers.markers.append(trace)
    return markers


def solve_path_request(solvers: Solver, arm: Arm, request: SolvePath.Request,
                       p: NodeParams, velocity: np.ndarray, header: Header
                       ) -> Tuple[int, str, PathResult, list, list]:
    """Code, message, result, trajectories and metrics of a ``SolvePath`` request.

    Every field is checked at the edge: frames, ``velocity_scaling`` in (0, 1] (0: 1), a
    timeout >= 0 (0: the node's ``path_timeout``), ``max_joint_step`` > 0 (0: the default),
    and times that fit ``builtin_interfaces/Duration``.

    Args:
        solvers: where to solve.
        arm: the served arm.
        request: the request (any field may be hostile).
        p: the parameters in force.
        velocity: the joints' velocity limits (n,) [rad/s].
        header: the trajectories' header.

    Raises:
        SikError: bad input (turned into its code by the guard), or no solver free in time.
    """
    if len(request.waypoints) > p.max_waypoints:
        raise InvalidGoal(f'{len(request.waypoints)} waypoints; at most {p.max_waypoints} are '
                          f'accepted (parameter max_waypoints)')
    positions, quats, frames = waypoints_from_msgs(request.waypoints, request.use_orientation)
    for i, frame in enumerate(frames):
        arm.check_frame(frame, f'waypoint {i}')
    scaling = request.velocity_scaling or 1.0
    if not 0.0 < scaling <= 1.0:
        raise InvalidGoal(f'velocity_scaling must be in (0, 1]; got {request.velocity_scaling}')
    timeout = conv.seconds_from_duration(request.timeout) or p.path_timeout
    seed = conv.seed_from_joint_state(request.seed, arm.joint_names)
    obstacles = conv.obstacles_from_msgs(request.obstacles, request.obstacle_poses,
                                         p.max_obstacles)
    step = request.max_joint_step if request.max_joint_step != 0 else PATH_DEFAULTS.max_joint_step
    result = solvers.solve_path(positions, quats, seed=seed,
                                num_paths=request.max_paths or PATH_DEFAULTS.num_paths,
                                max_joint_step=step, obstacles=obstacles, timeout=timeout)
    timed = [trajectory_msg(path, arm.joint_names, velocity, scaling, header)
             for path in result.paths]
    summary = (f'{len(result.paths)} paths through {len(positions)} waypoints, fraction '
               f'{result.fraction:.3f}, {result.elapsed * 1e3:.1f} ms')
    if result.success:
        code = Response.SUCCESS
    elif result.timed_out:
        code = Response.TIMEOUT
    else:
        code = Response.NO_SOLUTION
    text = summary if result.success else f'{result.message} ({summary})'
    return code, text, result, [t for t, _ in timed], [m for _, m in timed]
