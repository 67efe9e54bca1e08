"""Tier order, always: no solution of a higher tier precedes one of a lower tier.

The contract (docs/interfaces.md, "Obstacles"): ranking is lexicographic, tier first (free and
exact, free and inexact, colliding or self-colliding); within a tier, exact before inexact and
the families not yet in the answer before further solutions of families already in it. Checked
over hundreds of random pose and position goals on two arms (the bundled Panda and a UR5
bundle), half of them with a box beside a posture of the goal, each solution's tier checked
anew against the collision checker.
"""

import numpy as np
import pytest

from sik_ros.kinematics.chain import chain_forward
from sik_ros.solver import SelectiveIK
from sik_ros.solver.objectives import Obstacle, SeedDistance
from sik_ros.solver.results import COLLIDING, FREE_EXACT, FREE_INEXACT, NO_FAMILY


@pytest.fixture(scope='module')
def panda_ik():
    """The bundled Panda solver."""
    return SelectiveIK.load('panda')


@pytest.fixture(scope='module')
def ur5_ik(ur5_bundle):
    """A UR5 solver from a small ``sik-build`` bundle (6 joints, periodic limits)."""
    return SelectiveIK.load(str(ur5_bundle[0]))


def random_goals(ik, count, seed):
    """``count`` goals from random configurations: (position, quaternion or None, obstacles).

    Pose and position goals alternate; every other pair has a 20 cm box at the middle joint of
    the configuration the goal came from, so that some of the goal's postures collide.
    """
    rng = np.random.default_rng(seed)
    robot = ik.robot
    out = []
    while len(out) < count:
        q = rng.uniform(robot.lower, robot.upper)
        position, quat = ik.fk(q)
        if np.linalg.norm(position) < 0.15:
            continue
        _, _, origins, _ = chain_forward(robot.chain, q[None], frames=True)
        elbow = origins[0, origins.shape[1] // 2]
        box = Obstacle('box', (0.2, 0.2, 0.2), position=tuple(elbow))
        k = len(out)
        out.append((position, quat if k % 2 == 0 else None, [box] if k % 4 >= 2 else []))
    return out


def order_keys(ik, res, obstacles):
    """Each solution's (tier, inexact, a family already in the answer), tiers checked anew.

    The tier is recomputed from the checker: colliding when the posture touches the arm itself
    or an obstacle, else free and exact or free and inexact by the tolerances.
    """
    sols = res.solutions
    q = np.array([s.q for s in sols])
    selfc = ik.checker.self_collision(q)
    clear = ik.checker.clearance(q, obstacles)
    seen, keys = set(), []
    for s, hits, gap in zip(sols, selfc.tolist(), clear.tolist()):
        tier = COLLIDING if hits or gap <= 0 else (FREE_EXACT if s.converged else FREE_INEXACT)
        assert s.tier == tier, (s.tier, tier, s.self_collision, s.min_obstacle_distance)
        old = s.family != NO_FAMILY and s.family in seen
        keys.append((tier, not s.converged, old))
        seen.add(s.family)
    return keys


def check_order(ik, goals, **kw):
    """Every answer's keys non-decreasing; returns how many answers held two tiers."""
    mixed = 0
    for position, quat, obstacles in goals:
        res = ik.solve(position, quat, num_solutions=16, obstacles=obstacles, **kw)
        assert len(res.solutions) >= 1
        keys = order_keys(ik, res, obstacles)
        assert keys == sorted(keys), [k[0] for k in keys]
        mixed += len({k[0] for k in keys}) > 1
    return mixed


@pytest.mark.parametrize('arm', ['panda_ik', 'ur5_ik'])
def test_no_solution_of_a_higher_tier_precedes_one_of_a_lower(arm, request):
    """240 random goals (pose and position, with and without a box): the whole order holds."""
    ik = request.getfixturevalue(arm)
    mixed = check_order(ik, random_goals(ik, 240, seed=31))
    assert mixed >= 5, 'the draws hold answers of several tiers'


@pytest.mark.parametrize('arm', ['panda_ik', 'ur5_ik'])
def test_tier_order_holds_with_a_seed_and_an_objective(arm, request):
    """With a seed, and with a large objective, families and rounds never cross a tier."""
    ik = request.getfixturevalue(arm)
    goals = random_goals(ik, 60, seed=32)
    seed = np.clip(np.zeros(ik.robot.dof), ik.robot.lower, ik.robot.upper)
    mixed = check_order(ik, goals, seed=seed)
    mixed += check_order(ik, goals, objective=1e6 * SeedDistance(ik.robot.upper))
    assert mixed >= 3, 'the draws hold answers of several tiers'
