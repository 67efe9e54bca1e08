"""Where a ``~/solve_ik`` answer's time goes inside sik_node, stage by stage (no DDS).

A :class:`~sik_ros.ros.node.SikNode` in this process (the bundled Panda, its parameters'
defaults, markers on) answers requests of 16 solutions, goals at FK of random configurations
(position and pose goals alternating); each stage of an answer is timed on its own, in the order
the node runs them:

- ``request in``: the request's checks and conversions (frame, goal, count, seed, obstacles,
  timeout);
- ``solve``: the solver call as the node makes it (a clone borrowed, the settings in force), and
  ``solve, Python around the library``: that call less the library's own ``IKResult.elapsed``;
- ``posture indices``: the lazy encoding of the solutions' posture indices (first read by the
  messages);
- ``result code``: the answer's code and message;
- ``solution messages``: the 16 ``IKSolution`` messages;
- ``markers``: the ``MarkerArray`` of the answer and its serialisation (what a listening RViz
  costs), and ``markers check``: the check whether anyone listens;
- ``guard and statistics``: the request guard, its counts and the diagnostics' record;
- ``response serialised``: ``rclpy.serialization.serialize_message`` of the response (what
  ``send_response`` converts to C before DDS takes it);
- ``whole callback``: the service callback itself (``SikNode._on_solve_ik``), which runs every
  stage but the serialisation.

Then a cProfile of the whole callback: the functions of most own time.

Usage: ``python bench/node_stages.py [--requests N] [--profile-rows N] [--json PATH]``. The
figures are never asserted (see docs/benchmarks.md).
"""

import argparse
import cProfile
import io
import pstats
import sys
import time
from typing import Callable, Dict, List, Optional

import numpy as np
import rclpy
from rclpy.serialization import serialize_message
from rclpy.signals import SignalHandlerOptions

from sik_interfaces.srv import SolveIK
from sik_ros.ros import conversions as conv
from sik_ros.ros import launch
from sik_ros.ros.client import pose_request
from sik_ros.ros.ik_service import solution_msgs

from report import add_json_argument, write_json  # noqa: I100 (bench/report.py)
from service import NUM_SOLUTIONS, targets  # noqa: I100 (bench/service.py)


def timed(fn: Callable[[], object], into: List[float]):
    """Run ``fn``, append its wall time [s] to ``into``, return its value."""
    t0 = time.perf_counter()
    out = fn()
    into.append(time.perf_counter() - t0)
    return out


def stages(node, requests: List[SolveIK.Request]) -> Dict[str, List[float]]:
    """Each stage's time [s] for every request, in the node's order (see the module)."""
    names = ('request in', 'solve', 'solve, Python around the library', 'posture indices',
             'result code', 'solution messages', 'markers', 'markers check',
             'guard and statistics', 'response serialised', 'whole callback')
    out: Dict[str, List[float]] = {n: [] for n in names}
    arm, p, solvers = node.arm, node.params, node.solvers
    chain = node.ik.robot.chain
    for req in requests:
        t0 = time.perf_counter()
        position, orientation = conv.goal_from_pose(req.target.pose, req.use_orientation)
        arm.check_frame(req.target.header.frame_id, 'target')
        num, _ = conv.solution_count(req.max_solutions, p.num_solutions, p.max_solutions_cap)
        seed = conv.seed_from_joint_state(req.seed, arm.joint_names)
        obstacles = conv.obstacles_from_msgs(req.obstacles, req.obstacle_poses, p.max_obstacles)
        timeout = conv.seconds_from_duration(req.timeout) or p.timeout
        out['request in'].append(time.perf_counter() - t0)
        result = timed(lambda: solvers.solve(position, orientation, num, seed=seed,
                                             obstacles=obstacles, refine=p.refine,
                                             timeout=timeout), out['solve'])
        out['solve, Python around the library'].append(out['solve'][-1] - result.elapsed)
        timed(lambda: [s.posture_index for s in result.solutions], out['posture indices'])
        timed(lambda: conv.result_code(result, False, timeout), out['result code'])
        header = node._header()
        msgs = timed(lambda: solution_msgs(result, arm, header), out['solution messages'])
        timed(lambda: serialize_message(conv.posture_markers(
            chain, result.solutions, header, position, orientation)), out['markers'])
        timed(node.markers.want, out['markers check'])
        response = SolveIK.Response()
        response.solutions = msgs

        def guarded():
            return node.guard.answer('solve_ik', SolveIK.Response(),
                                     lambda r: (SolveIK.Response.SUCCESS, 'ok'))
        timed(guarded, out['guard and statistics'])
        timed(lambda: serialize_message(response), out['response serialised'])
        timed(lambda: node._on_solve_ik(req, SolveIK.Response()), out['whole callback'])
    return out


def profile(node, requests: List[SolveIK.Request], rows: int) -> str:
    """Profile the service callback (cProfile) over the requests: the top ``rows`` by own time."""
    prof = cProfile.Profile()
    prof.enable()
    for req in requests:
        node._on_solve_ik(req, SolveIK.Response())
    prof.disable()
    text = io.StringIO()
    pstats.Stats(prof, stream=text).sort_stats('tottime').print_stats(rows)
    return text.getvalue()


def main(argv: Optional[List[str]] = None) -> int:
    """Time the stages; print the table and the profile."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--requests', type=int, default=300)
    parser.add_argument('--profile-rows', type=int, default=25)
    parser.add_argument('-p', '--param', action='append', default=[],
                        help='a node parameter override name:=value (repeatable)')
    add_json_argument(parser)
    args = parser.parse_args(argv)
    ros_args = ['--ros-args', '--params-file', str(launch.params_file())]
    for item in args.param:
        ros_args += ['-p', item]
    rclpy.init(args=ros_args, signal_handler_options=SignalHandlerOptions.NO)
    from sik_ros.ros.node import SikNode  # noqa: I100 (after rclpy.init: its arguments)
    node = SikNode()
    try:
        goals = targets(args.requests + 20, seed=2, kinds='mixed')
        requests = [pose_request(pos, quat, max_solutions=NUM_SOLUTIONS) for pos, quat in goals]
        stages(node, requests[:20])  # warm-up
        times = stages(node, requests[20:])
        text = profile(node, requests[20:], args.profile_rows)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    rows = {name: {'p50_ms': float(np.median(t) * 1e3), 'mean_ms': float(np.mean(t) * 1e3)}
            for name, t in times.items()}
    width = max(len(n) for n in rows)
    print(f'sik_node stages, {args.requests} requests, mixed goals, {NUM_SOLUTIONS} solutions')
    print(f"| {'stage':<{width}} | p50 [ms] | mean [ms] |")
    for name, r in rows.items():
        print(f'| {name:<{width}} | {r["p50_ms"]:8.3f} | {r["mean_ms"]:9.3f} |')
    print(text)
    write_json(args.json, 'node_stages', {'requests': args.requests, 'stages': rows,
                                          'params': args.param})
    return 0


if __name__ == '__main__':
    sys.exit(main())
