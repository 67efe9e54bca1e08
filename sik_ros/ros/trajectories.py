"""Paths as ROS messages: waypoints in, ``trajectory_msgs/JointTrajectory`` and metrics out."""

from typing import List, Optional, Sequence, Tuple

from geometry_msgs.msg import PoseStamped
import numpy as np
from std_msgs.msg import Header
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from sik_interfaces.msg import PathMetrics
from sik_ros.errors import InvalidGoal
from sik_ros.ros.conversions import duration_from_seconds, known_clearance, MAX_DURATION
from sik_ros.solver import JointPath

#: Shortest time between two trajectory points [s].
MIN_SEGMENT = 1e-3


def waypoints_from_msgs(waypoints: Sequence[PoseStamped], use_orientation: bool
                        ) -> Tuple[np.ndarray, Optional[np.ndarray], List[str]]:
    """Positions (N, 3) [m], quaternions (N, 4) or None, and each waypoint's frame_id."""
    pos = np.array([[w.pose.position.x, w.pose.position.y, w.pose.position.z]
                    for w in waypoints], dtype=float).reshape(-1, 3)
    quat = np.array([[w.pose.orientation.x, w.pose.orientation.y, w.pose.orientation.z,
                      w.pose.orientation.w] for w in waypoints], dtype=float).reshape(-1, 4) \
        if use_orientation else None
    return pos, quat, [w.header.frame_id.lstrip('/') for w in waypoints]


def segment_times(q: np.ndarray, velocity: np.ndarray, scaling: float) -> np.ndarray:
    """Time from start of each row of ``q`` (N, n) [s]: each joint within its velocity limit.

    Every segment takes as long as its slowest joint needs at ``scaling`` times its limit
    [rad/s] (at least :data:`MIN_SEGMENT`), so the times strictly increase.

    Raises:
        InvalidGoal: at this ``scaling`` the path would last longer than a
            ``builtin_interfaces/Duration`` holds (or forever).
    """
    if len(q) < 2:
        return np.zeros(len(q))
    with np.errstate(divide='ignore', over='ignore', invalid='ignore'):
        # the distance in units of each joint's limit, then the scaling: no underflow to 0
        dt = (np.abs(np.diff(q, axis=0)) / velocity).max(axis=1) / scaling
    times = np.concatenate([[0.0], np.cumsum(np.maximum(dt, MIN_SEGMENT))])
    if not times[-1] <= MAX_DURATION:  # inf and NaN too
        raise InvalidGoal(f'velocity_scaling {scaling:g} makes the path last {times[-1]:g} s, '
                          f'beyond what builtin_interfaces/Duration holds '
                          f'({MAX_DURATION:.0f} s)')
    return times


def trajectory_msg(path: JointPath, joint_names: Sequence[str], velocity: np.ndarray,
                   scaling: float, header: Header) -> Tuple[JointTrajectory, PathMetrics]:
    """A joint path as a timed ``JointTrajectory`` and its ``PathMetrics``."""
    times = segment_times(path.q, velocity, scaling)
    traj = JointTrajectory(header=header, joint_names=list(joint_names))
    traj.points = [JointTrajectoryPoint(positions=q.tolist(),
                                        time_from_start=duration_from_seconds(t))
                   for q, t in zip(path.q, times)]
    metrics = PathMetrics(max_step=path.max_step, travel=path.travel,
                          min_obstacle_distance=known_clearance(path.min_obstacle_distance),
                          max_position_error=float(path.position_errors.max()),
                          max_orientation_error=float(path.orientation_errors.max()),
                          duration=float(times[-1]), cost=path.cost)
    return traj, metrics
