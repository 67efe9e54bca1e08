"""Ranking: tier first, then the cost within the tier, whatever the scale of the objective."""

import numpy as np
import pytest

from sik_ros.deadline import Deadline, NO_DEADLINE
from sik_ros.kinematics.chain import chain_forward
from sik_ros.solver import SelectiveIK
from sik_ros.solver.batch import Candidates
from sik_ros.solver.objectives import FromFunction, Obstacle, SeedDistance
from sik_ros.solver.ranking import rank
from sik_ros.solver.results import COLLIDING, FREE_EXACT, FREE_INEXACT, tier_label


@pytest.fixture(scope='module')
def ik():
    """The bundled Panda solver."""
    return SelectiveIK.load('panda')


def ordered(solutions):
    """Whether solutions are in (tier, exact first, a family's first first, score) order."""
    seen, keys = set(), []
    for s in solutions:
        keys.append((s.tier, not s.converged, s.family in seen, s.score))
        seen.add(s.family)
    return keys == sorted(keys)


def check_tiers(solutions):
    """Each solution's tier says what it is: free and exact, free and inexact, or colliding."""
    for s in solutions:
        if s.in_collision:
            assert s.tier == COLLIDING
        else:
            assert s.tier == (FREE_EXACT if s.converged else FREE_INEXACT)


def elbows(ik, q):
    """Origins of the middle joint of configurations (M, n) [m], (M, 3)."""
    _, _, origins, _ = chain_forward(ik.robot.chain, np.atleast_2d(q), frames=True)
    return origins[:, origins.shape[1] // 2]


def blocked_targets(ik, count=12):
    """Targets with a box beside the elbow of one of their postures (some solutions collide)."""
    rng = np.random.default_rng(11)
    robot = ik.robot
    out = []
    while len(out) < count:
        q = rng.uniform(robot.lower, robot.upper)
        position, _ = ik.fk(q)
        if not 0.25 < np.linalg.norm(position[:2]) < 0.7 or position[2] < 0.1:
            continue
        elbow = elbows(ik, q)[0]
        out.append((position, Obstacle('box', (0.25, 0.25, 0.25), position=tuple(elbow))))
    return out


@pytest.mark.parametrize('scale', [1e3, 1e4, 1e6])
def test_no_objective_lifts_a_colliding_solution_above_a_free_one(ik, scale):
    """With a large objective that prefers postures near the obstacle, free ones still lead."""
    mixed = 0
    for position, box in blocked_targets(ik):
        centre = np.asarray(box.position)
        near_box = FromFunction(
            lambda q, c=centre: scale * np.linalg.norm(elbows(ik, q) - c, axis=1))
        res = ik.solve(position, num_solutions=16, obstacles=[box], objective=near_box)
        check_tiers(res.solutions)
        assert ordered(res.solutions)
        tiers = [s.tier for s in res.solutions]
        if COLLIDING in tiers and FREE_EXACT in tiers:
            mixed += 1
            assert tiers.index(COLLIDING) > max(i for i, t in enumerate(tiers) if t != COLLIDING)
    assert mixed >= 3, 'the obstacles block some solutions of several targets'


def test_score_is_the_objective_within_the_free_exact_tier(ik):
    """A free exact solution's score is the objective's value of it, at any scale."""
    q0 = np.zeros(len(ik.joint_names))
    position, _ = ik.fk(np.clip(q0 + 0.3, ik.robot.lower, ik.robot.upper))
    objective = 1e6 * SeedDistance(q0)
    res = ik.solve(position, num_solutions=8, objective=objective)
    assert res.success
    for s in res.solutions:
        assert s.tier == FREE_EXACT
        assert s.score == pytest.approx(float(objective(s.q[None])[0]), rel=1e-12)
    assert ordered(res.solutions)


def test_tier_labels_name_what_a_solution_touches():
    """Tables show a colliding solution as obstacle or self-collision, not as a number."""
    assert tier_label(FREE_EXACT) == 'free'
    assert tier_label(FREE_INEXACT) == 'inexact'
    assert tier_label(COLLIDING, self_collision=True) == 'self-coll.'
    assert tier_label(COLLIDING) == 'obstacle'


def test_batched_self_collision_checks_match_one_at_a_time(ik):
    """Ranked self-collision flags are each configuration's own, free ones up to the limit."""
    rng = np.random.default_rng(5)
    robot = ik.robot
    q = rng.uniform(robot.lower, robot.upper, (60, robot.dof))
    own = ik.checker.self_collision(q)
    assert own.any() and (~own).sum() >= 8  # both kinds among the rows
    c = Candidates(q, np.zeros((60, 4), np.float32), np.zeros(60), np.zeros(60),
                   np.ones(60, dtype=bool))
    for limit in (1, 5, 8):
        sols = rank(ik.context, c, None, [], None, limit=limit, deadline=NO_DEADLINE)
        assert sum(not s.self_collision for s in sols) == limit
        for s in sols:
            assert s.self_collision == ik.checker.self_collision(s.q[None])[0]


def test_self_collision_checks_stop_at_the_deadline(ik):
    """Past its deadline the checker answers only the configurations it checked (the first)."""
    q = np.zeros((5, ik.robot.dof))
    assert len(ik.checker.self_collision(q, Deadline(0.0))) == 1
    assert len(ik.checker.self_collision(q)) == 5


def test_objectives_import_from_the_top_level():
    """``sik_ros.objectives`` and ``from sik_ros import ...`` name the solver's objectives."""
    import sik_ros
    import sik_ros.objectives as top
    from sik_ros.solver import objectives
    names = ['ElbowHeight', 'FromFunction', 'JointLimitMargin', 'Manipulability', 'Objective',
             'ObstacleClearance', 'SeedDistance', 'Sum', 'Weighted']
    for name in names:
        assert getattr(top, name) is getattr(objectives, name) is getattr(sik_ros, name)
        assert name in sik_ros.__all__
    assert len(names) == 9 and sorted(names) == top.__all__


def test_pose_answers_reported_free_are_free(ik):
    """Every pose answer outside the colliding tier is free of self-collision (checked anew).

    The spread rounds of a family follow its first, which a self-collision can move: the rows
    the new order brings forward are checked too. Uniform goals, some of whose answers touch
    the arm itself; rounds keep the tiers: no free solution after a colliding one.
    """
    checker = ik.context.checker
    rng = np.random.default_rng(6)
    mixed = 0
    for _ in range(40):
        q = rng.uniform(ik.robot.lower, ik.robot.upper)
        res = ik.solve(*ik.fk(q), num_solutions=16)
        sols = [s for s in res.solutions if s.converged]
        hits = checker.self_collision(np.array([s.q for s in sols]))
        assert [s.self_collision for s in sols] == hits.tolist()
        firsts = len({s.family for s in sols})
        tiers = [s.tier for s in sols[firsts:]]
        assert tiers == sorted(tiers)
        mixed += bool(hits.any())
    assert mixed >= 3  # these draws hold self-colliding answers
