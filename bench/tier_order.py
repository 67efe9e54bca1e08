"""Benchmark of the ranking contract: tier inversions over random goals, library and node.

The contract (docs/interfaces.md, "Obstacles"): no solution of a higher tier (free and exact,
free and inexact, colliding) comes before one of a lower tier, and within a tier a family's
first comes before further solutions of families already in the answer. For each arm, goals
at FK of random configurations, pose and position alternating, every other pair with a 20 cm
box at the middle joint of the configuration the goal came from (some postures collide), 16
solutions each, no seed; each answer's tiers checked anew against the collision checker
(self-collision, clearance) and counted as an inversion when the order breaks. With
``--node`` the same goals of the first arm go through ``~/solve_ik`` of a ``sik_node`` started
here, the tiers read from the answer's own fields.

Usage: ``python bench/tier_order.py [--goals N] [--bundle DIR ...] [--node] [--json PATH]``
(default: 1,000 goals on the bundled Panda). Prints a table; nothing is asserted.
"""

import argparse
import subprocess
import sys
from typing import Dict, List, Optional

import numpy as np

from sik_ros.kinematics.chain import chain_forward
from sik_ros.solver import SelectiveIK
from sik_ros.solver.objectives import Obstacle
from sik_ros.solver.results import COLLIDING, FREE_EXACT, FREE_INEXACT, NO_FAMILY

from report import add_json_argument, write_json  # noqa: I100 (bench/report.py)

BOX = 0.2  # [m] side of the box at the middle joint
NUM_SOLUTIONS = 16


def goals(ik: SelectiveIK, count: int, seed: int = 7) -> List[tuple]:
    """``count`` random goals: (position, quaternion or None, obstacles) (module doc)."""
    rng = np.random.default_rng(seed)
    robot = ik.robot
    out = []
    while len(out) < count:
        q = rng.uniform(robot.lower, robot.upper)
        position, quat = ik.fk(q)
        _, _, origins, _ = chain_forward(robot.chain, q[None], frames=True)
        elbow = origins[0, origins.shape[1] // 2]
        k = len(out)
        box = [Obstacle('box', (BOX,) * 3, position=tuple(elbow))] if k % 4 >= 2 else []
        out.append((position, quat if k % 2 == 0 else None, box))
    return out


def inverted(keys: List[tuple]) -> bool:
    """Whether an answer's (tier, inexact, a family already in the answer) keys break order."""
    return keys != sorted(keys)


def library(ik: SelectiveIK, targets: List[tuple]) -> Dict[str, float]:
    """Inversions and wrong tiers of the library's answers, tiers checked anew."""
    bad = wrong = mixed = solutions = 0
    for position, quat, obstacles in targets:
        res = ik.solve(position, quat, num_solutions=NUM_SOLUTIONS, obstacles=obstacles)
        q = np.array([s.q for s in res.solutions])
        selfc = ik.checker.self_collision(q) if len(q) else []
        clear = ik.checker.clearance(q, obstacles) if len(q) else []
        seen, keys = set(), []
        for s, hit, gap in zip(res.solutions, list(selfc), list(clear)):
            tier = COLLIDING if hit or gap <= 0 else (FREE_EXACT if s.converged
                                                      else FREE_INEXACT)
            wrong += tier != s.tier
            keys.append((tier, not s.converged, s.family != NO_FAMILY and s.family in seen))
            seen.add(s.family)
        bad += inverted(keys)
        mixed += len({k[0] for k in keys}) > 1
        solutions += len(keys)
    return dict(goals=len(targets), inversions=bad, wrong_tiers=wrong, mixed=mixed,
                solutions=solutions)


def through_node(model_dir: Optional[str], targets: List[tuple], tol) -> Dict[str, float]:
    """Inversions of ``~/solve_ik``'s answers to the same goals, tiers from the answers."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from sik_ros.ros import launch
    from sik_ros.ros.client import box, pose_request, SolveIKClient
    env = launch.ros_env()
    proc = launch.launch_node(model_dir, env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.STDOUT)
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    bad = mixed = answered = wrong = 0
    try:
        with SolveIKClient(node_name='sik_bench_tiers') as client:
            if not client.wait_for_service(90.0):
                raise SystemExit(f'sik_node did not come up (exit code {proc.poll()})')
            for position, quat, obstacles in targets:
                req = pose_request(position, quat, NUM_SOLUTIONS)
                req.timeout.sec = 1
                for o in obstacles:
                    shape, pose = box(o.position, o.dimensions)
                    req.obstacles.append(shape)
                    req.obstacle_poses.append(pose)
                answer = client.call(req, timeout=10.0)
                if answer is None:
                    continue
                answered += 1
                seen, keys = set(), []
                for s in answer.solutions:
                    exact = s.position_error <= tol[0] and (quat is None
                                                            or s.orientation_error <= tol[1])
                    colliding = s.self_collision or not s.min_obstacle_distance > 0
                    tier = COLLIDING if colliding else FREE_EXACT if exact else FREE_INEXACT
                    wrong += tier != s.tier
                    keys.append((tier, not exact, s.family in seen))
                    seen.add(s.family)
                bad += inverted(keys)
                mixed += len({k[0] for k in keys}) > 1
    finally:
        launch.stop_node(proc)
        rclpy.try_shutdown()
    return dict(goals=len(targets), answered=answered, inversions=bad, wrong_tiers=wrong,
                mixed=mixed)


def main(argv=None) -> int:
    """Run the benchmark and print its table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--goals', type=int, default=1000, help='goals per arm')
    parser.add_argument('--bundle', action='append', default=[],
                        help='another arm\'s bundle directory (repeatable)')
    parser.add_argument('--node', action='store_true', help='also through ~/solve_ik')
    add_json_argument(parser)
    args = parser.parse_args(argv)
    rows = {}
    for name in ['panda'] + args.bundle:
        ik = SelectiveIK.load(name)
        targets = goals(ik, args.goals)
        rows[ik.robot.name] = library(ik, targets)
        if args.node and name == 'panda':
            tol = (ik.config.position_tolerance, ik.config.orientation_tolerance)
            rows[ik.robot.name + ' (~/solve_ik)'] = through_node(None, targets, tol)
    print('| arm | goals | answers with several tiers | tier inversions | wrong tiers |')
    print('|---|---|---|---|---|')
    for arm, r in rows.items():
        print(f"| {arm} | {r['goals']} | {r['mixed']} | {r['inversions']} | "
              f"{r['wrong_tiers']} |")
    write_json(args.json, 'tier_order', rows)
    return 0


if __name__ == '__main__':
    sys.exit(main())
