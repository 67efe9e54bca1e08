"""Posture families: labels, their numbering, the order they give, the one-per-family option."""

import numpy as np
import pytest

from sik_ros.deadline import NO_DEADLINE
from sik_ros.defaults import SEARCH_SEED_TABLE_ROWS
from sik_ros.errors import InvalidArgument
from sik_ros.kernels.angles import TURN
from sik_ros.kernels.atlas import _off_chords
from sik_ros.kernels.atlas_points import spread_points
from sik_ros.kernels.families import branch_labels
from sik_ros.kinematics.rotations import quaternion_matrix
from sik_ros.solver import families, SelectiveIK, SolverConfig
from sik_ros.solver.batch import Candidates
from sik_ros.solver.context import Goal
from sik_ros.solver.pipeline import distinct_postures
from sik_ros.solver.results import NO_FAMILY, result_to_dict


@pytest.fixture(scope='module')
def bundled():
    """The bundled Panda solver."""
    return SelectiveIK.load('panda')


def pose_goals(ik, count, seed=0):
    """Reachable pose goals: FK of configurations drawn within the limits."""
    rng = np.random.default_rng(seed)
    return [ik.fk(rng.uniform(ik.robot.lower, ik.robot.upper)) for _ in range(count)]


def test_families_numbered_by_first_appearance_and_distinct_first(bundled):
    """Labels run 0, 1, ... in first appearance; the first answers come from distinct ones."""
    for pos, quat in pose_goals(bundled, 6):
        res = bundled.solve(pos, quat, num_solutions=16)
        exact = [s for s in res.solutions if s.converged]
        assert exact and all(s.family != NO_FAMILY for s in exact)
        labels = [s.family for s in exact]
        seen = []
        for f in labels:
            if f not in seen:
                assert f == len(seen)
                seen.append(f)
        assert res.num_families >= len(seen)
        # every family of the answer appears before any family's second solution
        free = [s.family for s in exact if s.tier == 0]
        k = len(set(free))
        assert sorted(free[:k]) == sorted(set(free))


def test_one_per_family_keeps_the_best_of_each(bundled):
    """With one_per_family the answer holds each family once, as the full answer's first."""
    pos, quat = pose_goals(bundled, 1, seed=3)[0]
    full = bundled.solve(pos, quat, num_solutions=16)
    one = bundled.solve(pos, quat, num_solutions=16, one_per_family=True)
    labels = [s.family for s in one.solutions]
    assert len(labels) >= 1 and labels == list(range(len(labels)))
    assert one.num_families == full.num_families
    firsts = {}
    for s in full.solutions:
        firsts.setdefault(s.family, s)
    assert len(firsts) == len(labels)
    for s in one.solutions:
        assert np.allclose(s.q, firsts[s.family].q)


def test_one_per_family_by_config_and_bad_values(bundled):
    """The option is a SolverConfig field too; anything but a bool is refused."""
    ik = bundled.with_config(one_per_family=True)
    pos, quat = pose_goals(bundled, 1, seed=4)[0]
    res = ik.solve(pos, quat, num_solutions=16)
    assert len({s.family for s in res.solutions}) == len(res.solutions)
    with pytest.raises(InvalidArgument, match='one_per_family'):
        SolverConfig(one_per_family=1)
    with pytest.raises(InvalidArgument, match='one_per_family'):
        bundled.solve(pos, quat, one_per_family='yes')


def test_one_solution_is_family_zero_of_one(bundled):
    """A single answer names its family 0 and knows of one family at least."""
    pos, quat = pose_goals(bundled, 1, seed=5)[0]
    res = bundled.solve(pos, quat, num_solutions=1)
    assert res.success and res.solutions[0].family == 0 and res.num_families >= 1


def test_json_view_carries_families(bundled):
    """sik-solve --json shows each solution's family and the families found."""
    pos, quat = pose_goals(bundled, 1, seed=6)[0]
    res = bundled.solve(pos, quat, num_solutions=4)
    view = result_to_dict(res, bundled.joint_names)
    assert view['num_families'] == res.num_families
    assert [s['family'] for s in view['solutions']] == [s.family for s in res.solutions]


def test_segment_links_split_no_traced_family(bundled):
    """Solutions a corrected segment links lie on one traced self-motion curve (Panda)."""
    ctx = bundled.context
    pairs = 0
    for pos, quat in pose_goals(bundled, 4, seed=7):
        res = bundled.solve(pos, quat, num_solutions=16)
        q = np.array([s.q for s in res.solutions if s.converged])
        goal = Goal(np.asarray(pos, float), quaternion_matrix(quat))
        linked = families.labels(ctx, q, goal, NO_DEADLINE)
        traced = families.traced(ctx, q, goal, NO_DEADLINE)
        for i in range(len(q)):
            for j in range(i + 1, len(q)):
                if linked[i] == linked[j]:
                    assert traced[i] == traced[j]
                    pairs += 1
    assert pairs >= 8  # linked pairs were checked


def test_branch_labels_are_equal_modulo_turns(ur5):
    """Rows equal modulo 2 pi on periodic joints share a branch; rows apart do not."""
    rng = np.random.default_rng(0)
    base = rng.uniform(-np.pi, np.pi, (3, 6))
    base[1] = base[0] + 1.0
    shifted = base[0] + TURN * np.array([1, 0, -1, 0, 0, 1]) + 1e-6
    q = np.ascontiguousarray(np.vstack([base, shifted]))
    labels = branch_labels(q, 0.1, np.ones(6, dtype=bool))
    assert labels[3] == labels[0] and len({labels[0], labels[1], labels[2]}) == 3
    # without periodic joints a whole turn is another branch
    assert branch_labels(q, 0.1, np.zeros(6, dtype=bool))[3] == 3


def test_ur5_families_are_its_branches_every_one(ur5_bundle):
    """On a 6-joint arm a family is a branch (angles wrapped), and every branch is found.

    The branches known: ours and those of 300 refinements from uniform random starts.
    """
    from test_branches import every_branch
    ik = SelectiveIK.load(ur5_bundle[0])
    rng = np.random.default_rng(1)
    checked = 0
    for t in range(8):
        q0 = rng.uniform(ik.robot.lower, ik.robot.upper)
        res = ik.solve(*ik.fk(q0), num_solutions=16)
        exact = [s for s in res.solutions if s.converged]
        q = np.ascontiguousarray([s.q for s in exact])
        assert len(q) >= 2  # a UR5 pose has 2 to 8 branches (and their 2 pi equivalents)
        reference = every_branch(ik.robot, q0, seed=t)
        branch = branch_labels(np.ascontiguousarray(np.concatenate([q, reference])), 0.1,
                               np.ones(6, dtype=bool))
        for i in range(len(q)):
            for j in range(i + 1, len(q)):
                assert (branch[i] == branch[j]) == (exact[i].family == exact[j].family)
        known = len(set(branch.tolist()))
        assert len(set(branch[:len(q)].tolist())) == known == res.num_families
        checked += known
    assert checked >= 8 * 2


def test_isolated_branches_are_not_merged_as_near_postures(ur5_bundle, bundled):
    """At a 6-joint pose, exact rows 0.3 rad apart stay two; a 7-joint arm's merge."""
    for ik, keep in ((SelectiveIK.load(ur5_bundle[0]), 2), (bundled, 1)):
        q0 = (ik.robot.lower + ik.robot.upper) / 4
        q = np.stack([q0, q0 + 0.3 / np.sqrt(ik.robot.dof), q0 + 0.01])
        pos, quat = ik.fk(q0)
        goal = Goal(np.asarray(pos, float), quaternion_matrix(quat))
        c = Candidates(q, np.zeros((3, 4), np.float32), np.zeros(3), np.zeros(3),
                       np.ones(3, dtype=bool))
        assert ik.config.distinct_threshold > 0.3
        kept = distinct_postures(ik.context, c, goal, None)
        # postures modulo 2 pi (a UR5's equivalents added); the third row, 0.01 rad from the
        # first, is the first found twice
        postures = branch_labels(np.ascontiguousarray(kept.q), 0.05,
                                 np.asarray(ik.robot.periodic, dtype=bool))
        assert len(set(postures.tolist())) == keep


def test_near_solutions_of_two_atlas_pieces_are_both_kept(bundled):
    """Two exact rows nearer than distinct_threshold stay two when the atlas parts them.

    A small family beside a large one, parted from it by a joint limit, keeps its solution;
    two rows of one piece (or with no atlas) are one posture.
    """
    from sik_ros.solver.families.search import Atlas
    ik = bundled
    q0 = (ik.robot.lower + ik.robot.upper) / 2
    q = np.stack([q0, q0 + 0.2 / np.sqrt(ik.robot.dof)])
    pos, quat = ik.fk(q0)
    goal = Goal(np.asarray(pos, float), quaternion_matrix(quat))
    c = Candidates(q, np.zeros((2, 4), np.float32), np.zeros(2), np.zeros(2),
                   np.ones(2, dtype=bool))
    assert ik.config.distinct_threshold > 0.2
    assert len(distinct_postures(ik.context, c, goal, None)) == 1
    two = Atlas(q.copy(), np.array([0, 1]), 0.05)
    assert len(distinct_postures(ik.context, c, goal, None, two)) == 2
    one = Atlas(q.copy(), np.array([0, 0]), 0.05)
    assert len(distinct_postures(ik.context, c, goal, None, one)) == 1


def test_every_searched_family_is_in_the_answer_in_tier_order(bundled):
    """With the search, the answer holds each family's best, colliding or not, in tier order.

    As an analytic solver's answer holds every family: one that touches the arm itself is in
    the answer, reported so, after the free solutions (the tier first); within a tier the
    families' firsts come before further solutions.
    """
    colliding_firsts = 0
    for pos, quat in pose_goals(bundled, 12, seed=5):
        res = bundled.solve(pos, quat, num_solutions=16)
        exact = [s for s in res.solutions if s.converged]
        labels = [s.family for s in exact]
        k = len(set(labels))
        assert k >= 1 and sorted(set(labels)) == list(range(k))
        if res.num_families <= 16:
            assert k == res.num_families
        seen, keys = set(), []
        for s in res.solutions:
            keys.append((s.tier, not s.converged, s.family in seen))
            seen.add(s.family)
        assert keys == sorted(keys)
        # a colliding family's best in the answer, after free seconds
        firsts = {s.family: s for s in reversed(exact)}
        colliding_firsts += any(s.tier != 0 for s in firsts.values()) and \
            sum(s.tier == 0 for s in exact) > sum(s.tier == 0 for s in firsts.values())
    assert colliding_firsts >= 1  # these draws hold such families


def test_rounds_take_each_familys_first_then_its_farthest_rows():
    """Round 0 is a family's first row in the order, each later its farthest row.

    Farthest from the rows of the rounds before (checked by brute force), whatever the roots'
    numbering; without spreading, every later row is round 1.
    """
    rng = np.random.default_rng(2)
    periodic = np.zeros(3, dtype=bool)
    for _ in range(50):
        m = int(rng.integers(1, 12))
        fam = rng.integers(-1, m, m)
        order = rng.permutation(m)
        q = rng.uniform(-3, 3, (m, 3))
        got = families.rounds(fam, order, q, periodic)
        assert (got == families.rounds(fam + 100 * (fam >= 0), order, q, periodic)).all()
        assert (got[fam < 0] == 0).all()
        assert (families.rounds(fam, order, q, periodic, False) == np.minimum(got, 1)).all()
        for f in set(fam.tolist()) - {-1}:
            rows = [i for i in order if fam[i] == f]
            given = [rows[0]]
            while len(given) < len(rows):
                far = [min(np.linalg.norm(q[i] - q[j]) for j in given) if i not in given
                       else -1.0 for i in rows]
                given.append(rows[int(np.argmax(far))])
            assert [int(got[i]) for i in given] == list(range(len(rows)))


def test_family_search_adds_exact_points_within_limits_far_apart_per_family(bundled):
    """The atlas's points reach the pose (Pinocchio FK) within the limits, each family's apart.

    Apart: every point the search adds is ``distinct_threshold`` from the solutions it traced
    from and from the others of its piece; the Panda has one exact flip.
    """
    from sik_ros.kinematics.branches import robot_flips as flips_of
    from sik_ros.solver.explore import unindexed
    from sik_ros.solver.scores import assess
    from sik_ros.solver.families.search import search
    robot, cfg, ctx = bundled.robot, bundled.config, bundled.context
    assert flips_of(robot).tolist() == [0]  # the Panda's spherical shoulder
    added = 0
    for pos, quat in pose_goals(bundled, 6, seed=3):
        res = bundled.with_config(family_search=False).solve(pos, quat, num_solutions=16)
        q = np.ascontiguousarray([s.q for s in res.solutions if s.converged])
        goal = Goal(np.asarray(pos, float), quaternion_matrix(quat))
        c = assess(q, unindexed(q, 2), np.zeros(len(q)), np.zeros(len(q)), 'pose', cfg)
        out, atlas = search(ctx, c, goal, NO_DEADLINE)
        assert atlas is not None and len(atlas.points) > 0
        new = out.q[len(q):]
        pieces = atlas.pieces_of(new, robot.periodic)
        for k, x in enumerate(new):
            tip = robot.pin_placement(x)
            assert np.linalg.norm(tip.translation - pos) <= cfg.position_tolerance
            dr = tip.rotation.T @ goal.rotation
            assert np.arccos(np.clip((np.trace(dr) - 1) / 2, -1, 1)) <= \
                cfg.orientation_tolerance
            assert np.all(x >= robot.lower) and np.all(x <= robot.upper)
            same = pieces == pieces[k]
            same[k] = False
            near = np.linalg.norm(new[same] - x, axis=1) if same.any() else np.array([np.inf])
            assert near.min() >= cfg.distinct_threshold - 1e-9
        assert np.all(out.exact[len(q):])
        added += len(new)
    assert added >= 6  # points were added and checked


def test_default_labels_are_the_traced_curves_both_ways(bundled):
    """The answer's families are the traced self-motion curves within the limits, both ways.

    Solutions on one traced curve share a family (no curve split in two), and solutions of
    one family lie on one traced curve (no two curves joined): "the search finds more
    families" cannot pass by splitting. The reference: :func:`families.traced`, each
    solution's curve followed within the limits in steps of 0.1 rad.
    """
    ctx = bundled.context
    pairs = split = joined = 0
    for pos, quat in pose_goals(bundled, 8, seed=7):
        res = bundled.solve(pos, quat, num_solutions=16)
        exact = [s for s in res.solutions if s.converged]
        q = np.array([s.q for s in exact])
        goal = Goal(np.asarray(pos, float), quaternion_matrix(quat))
        traced = families.traced(ctx, q, goal, NO_DEADLINE)
        for i in range(len(q)):
            for j in range(i + 1, len(q)):
                ours = exact[i].family == exact[j].family
                curve = traced[i] == traced[j]
                split += curve and not ours
                joined += ours and not curve
                pairs += 1
    assert pairs >= 100
    assert split == 0 and joined == 0


def test_family_search_finds_more_families(bundled):
    """Without the search no pose has more families, and some have fewer; every answer exact."""
    cfg = bundled.config
    assert cfg.family_search  # on by default
    plain = bundled.with_config(family_search=False)
    more = 0
    for pos, quat in pose_goals(bundled, 10, seed=11):
        without = plain.solve(pos, quat, num_solutions=16)
        with_search = bundled.solve(pos, quat, num_solutions=16)
        assert with_search.num_families >= without.num_families
        more += with_search.num_families > without.num_families
        exact = [s for s in with_search.solutions if s.converged]
        assert len(exact) >= 2
        for s in exact:
            tip = bundled.robot.pin_placement(s.q)
            assert np.linalg.norm(tip.translation - pos) <= cfg.position_tolerance
    assert more >= 2


def test_mirrored_solutions_are_exact_and_reach_the_elbows_other_side(bundled):
    """Solutions mirrored across the held arm's singular angles refine onto the pose.

    Each is exact (Pinocchio FK) and within the limits; on some poses the search's answer
    has solutions on both sides of the Panda's elbow stretched where the answer without it
    has one side only: curves the table's starts do not reach.
    """
    from sik_ros.solver.families.search import mirrored, robot_mirrors
    robot, cfg, ctx = bundled.robot, bundled.config, bundled.context
    joints, centres = robot_mirrors(robot)
    assert 3 in joints.tolist() and 6 not in joints.tolist()  # the elbow; never the held one
    assert 1 not in joints.tolist()  # the shoulder flip's middle joint: its twins are traced
    stretch = centres[joints == 3][0]
    plain = bundled.with_config(family_search=False)
    sides, found = 0, 0
    for k, (pos, quat) in enumerate(pose_goals(bundled, 30, seed=7)):
        res = plain.solve(pos, quat, num_solutions=16)
        q = np.ascontiguousarray([s.q for s in res.solutions if s.converged])
        goal = Goal(np.asarray(pos, float), quaternion_matrix(quat))
        for x in mirrored(ctx, q, goal, NO_DEADLINE) if k < 10 else ():
            tip = robot.pin_placement(x)
            assert np.linalg.norm(tip.translation - pos) <= cfg.position_tolerance
            assert np.all(x >= robot.lower) and np.all(x <= robot.upper)
            found += 1
        full = bundled.solve(pos, quat, num_solutions=16)

        def side(r):
            return {bool(np.sin(s.q[3] - stretch) > 0) for s in r.solutions if s.converged}
        sides += len(side(full)) > len(side(res))
    assert found >= 12 and sides >= 2


def test_every_piece_of_the_atlas_has_a_candidate(bundled):
    """The search's candidates lie on every piece of its atlas.

    A piece that only a mirrored start reached gets a point of its own, as one that no found
    solution lies on does.
    """
    from sik_ros.solver.explore import unindexed
    from sik_ros.solver.scores import assess
    from sik_ros.solver.families.search import search
    robot, cfg, ctx = bundled.robot, bundled.config, bundled.context
    plain = bundled.with_config(family_search=False)
    pieces = 0
    for pos, quat in pose_goals(bundled, 12, seed=21):
        res = plain.solve(pos, quat, num_solutions=16)
        q = np.ascontiguousarray([s.q for s in res.solutions if s.converged])
        goal = Goal(np.asarray(pos, float), quaternion_matrix(quat))
        c = assess(q, unindexed(q, 2), np.zeros(len(q)), np.zeros(len(q)), 'pose', cfg)
        out, atlas = search(ctx, c, goal, NO_DEADLINE)
        on = set(atlas.pieces_of(out.q[out.exact], robot.periodic).tolist())
        assert set(atlas.pieces.tolist()) <= on
        pieces += len(set(atlas.pieces.tolist()))
    assert pieces >= 24


def test_the_search_starts_from_the_seed_table_too(bundled):
    """The bundle's seed table gives the search starts no model posture leads to.

    A 7-joint arm's bundle has a small seed table; on a pose two of whose families no model
    posture reaches, the default answer holds them and one without those starts lacks them,
    and every curve it found is among the default's (each family a traced curve, as above).
    """
    ctx = bundled.context
    assert bundled.config.family_seed_starts > 0
    assert len(ctx.models['pose'].seeds) == SEARCH_SEED_TABLE_ROWS
    with pytest.raises(InvalidArgument, match='family_seed_starts'):
        SolverConfig(family_seed_starts=-1)
    pos, quat = bundled.fk(np.array([-0.258, 1.293, -0.15, -0.431, 0.657, 3.02, -0.638]))
    seeded = bundled.solve(pos, quat, num_solutions=16)
    without = bundled.with_config(family_seed_starts=0).solve(pos, quat, num_solutions=16)
    assert seeded.num_families >= without.num_families + 2
    q_seeded = np.array([s.q for s in seeded.solutions if s.converged])
    q_without = np.array([s.q for s in without.solutions if s.converged])
    assert len(q_seeded) == len(seeded.solutions)
    goal = Goal(np.asarray(pos, float), quaternion_matrix(quat))
    curves = families.traced(ctx, np.concatenate([q_seeded, q_without]), goal, NO_DEADLINE)
    assert set(curves[len(q_seeded):]) <= set(curves[:len(q_seeded)])
    for q in q_seeded:
        tip = bundled.robot.pin_placement(q)
        assert np.linalg.norm(tip.translation - pos) <= bundled.config.position_tolerance


def test_spread_points_take_each_pieces_farthest_points():
    """Each point a piece gets is its farthest from its rows and the points taken before.

    While at least the spacing from them, up to four per piece (a piece no row lies on gets
    its middle recorded point first); checked by brute force.
    """
    rng = np.random.default_rng(4)
    periodic = np.zeros(7, dtype=bool)
    for _ in range(20):
        count = int(rng.integers(5, 60))
        points = np.cumsum(rng.normal(0, 0.2, (count, 7)), axis=0)
        piece = np.sort(rng.integers(0, 3, count))
        rows = points[rng.choice(count, 2, replace=False)] + rng.normal(0, 0.01, (2, 7))
        row_piece = np.array([piece[np.argmin(np.linalg.norm(points - r, axis=1))]
                              for r in rows], dtype=np.int64)
        out, out_piece = np.empty((64, 7)), np.empty(64, dtype=np.int64)
        k = spread_points(points, piece, count, rows, row_piece, periodic, 0.5, 4, out,
                          out_piece)
        for f in set(piece.tolist()):
            mine = points[piece == f]
            given = [r for r, p in zip(rows, row_piece) if p == f]
            taken = [out[e] for e in range(k) if out_piece[e] == f]
            total = len(taken)
            if not given:  # a piece no row lies on: its middle recorded point first
                given, taken = taken[:1], taken[1:]
            for x in taken:
                far = [min(np.linalg.norm(y - g) for g in given) for y in mine]
                assert min(np.linalg.norm(x - g) for g in given) == pytest.approx(max(far))
                assert max(far) >= 0.5
                given.append(x)
            far = [min(np.linalg.norm(y - g) for g in given) for y in mine]
            assert total == 4 or max(far) < 0.5


def test_a_point_on_a_records_chords_is_on_its_curve():
    """The distance to a recorded point's chords: 0 on them, the offset beside them.

    Chords only to the neighbours of its piece within 1.5 steps (not to another piece's point,
    nor across a gap a trace's second way leaves).
    """
    periodic = np.zeros(7, dtype=bool)
    points = np.zeros((4, 7))
    points[:, 0] = [0.0, 0.25, 0.5, 2.0]
    piece = np.array([0, 0, 0, 0])
    x = np.zeros(7)
    x[0] = 0.375
    assert _off_chords(x, points, piece, 4, 1, 0.25, periodic) == pytest.approx(0.0)
    x[1] = 0.03
    assert _off_chords(x, points, piece, 4, 1, 0.25, periodic) == pytest.approx(0.03)
    x[:] = 0.0
    x[0] = 1.25  # on the segment to the point 1.5 rad on: no chord, the distance to the point
    assert _off_chords(x, points, piece, 4, 2, 0.25, periodic) == pytest.approx(0.75)
    piece[2] = 1  # another piece's point: no chord to it
    x[0] = 0.375
    assert _off_chords(x, points, piece, 4, 1, 0.25, periodic) == pytest.approx(0.125)
