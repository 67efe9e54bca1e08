"""Seed tables: dataset configurations by tip pose, the starts of pose solutions."""

import json
import shutil

import numpy as np
import pytest

from arm_urdfs import chain_text
from sik_ros.bundles.bundle import add_to_bundle, load_bundle
from sik_ros.defaults import SEARCH_SEED_TABLE_ROWS
from sik_ros.errors import ArtifactMismatch, CorruptArtifact, InvalidArgument
from sik_ros.kinematics.robots import load_robot
from sik_ros.solver.ranking import posture_mask
from sik_ros.tables.dataset import collect
from sik_ros.tables.seed_table import (DEFAULT_ROWS, default_rows, first_axis, NEIGHBOURS,
                                       QUATERNION_SCALE, SeedTable)


@pytest.fixture(scope='module')
def ur5_data(ur5, tmp_path_factory):
    """8,000 UR5 configurations drawn uniformly (periodic joints over one turn)."""
    return collect(ur5, tmp_path_factory.mktemp('ds') / 'ur5', sampler='uniform', samples=8000,
                   seed=4)


@pytest.fixture(scope='module')
def table(ur5, ur5_data):
    """A seed table of 3,000 of them."""
    return SeedTable.build(ur5, ur5_data, rows=3000, seed=1)


@pytest.mark.slow
def test_a_seed_table_keeps_dataset_rows_and_round_trips(ur5, ur5_data, table, tmp_path):
    """Its rows are dataset configurations (to 16-bit precision), the same after save and load."""
    assert len(table) == 3000
    data = np.asarray(ur5_data.q)
    nearest = np.abs(table.q[:, None, :] - data[None, :, :]).max(axis=2).min(axis=1)
    assert nearest.max() < 4 * np.pi / 65535  # one code step over a 4 pi range
    loaded = SeedTable.load(table.save(tmp_path / 'seeds.npz'), ur5)
    np.testing.assert_array_equal(loaded.q, table.q)
    assert loaded.manifest['rows'] == 3000 and loaded.manifest['robot'] == ur5.manifest()


def test_rows_are_kept_in_the_trees_leaf_order_with_the_same_starts(ur5, table):
    """A leaf's rows lie together in memory; shuffled rows give the same rows and starts."""
    # built on rows in its own leaf order, the tree keeps them in it (a saved table loads so)
    np.testing.assert_array_equal(SeedTable(ur5, table.q, table.manifest).tree.order,
                                  np.arange(len(table)))
    shuffled = SeedTable(ur5, table.q[np.random.default_rng(0).permutation(len(table))],
                         table.manifest)
    np.testing.assert_array_equal(SeedTable(ur5, shuffled.q, table.manifest).tree.order,
                                  np.arange(len(table)))
    np.testing.assert_array_equal(np.unique(shuffled.q, axis=0), np.unique(table.q, axis=0))
    for q in np.random.default_rng(1).uniform(ur5.lower, ur5.upper, (5, ur5.dof)):
        p, quat = ur5.fk(q)
        np.testing.assert_array_equal(shuffled.starts(p, quat, 24), table.starts(p, quat, 24))


def test_starts_are_the_nearest_rows_by_tip_pose_and_far_apart(ur5, table):
    """A goal at a row's own tip pose starts from that row; the other starts are far apart."""
    q0 = table.q[123]
    p, quat = ur5.fk(q0)
    starts = table.starts(p, quat, 12)
    assert starts.shape == (12, 6)
    np.testing.assert_allclose(starts[0], q0)  # the nearest first
    angles = np.concatenate([np.cos(starts), np.sin(starts)], axis=1)
    gaps = np.linalg.norm(angles[:, None] - angles[None], axis=2) + 9 * np.eye(12)
    assert gaps.min() > 0.3
    # every start is among the 100 rows nearest the goal in the table's key space: tip poses
    # in a frame along the first joint's axis, turned to azimuth 0 (position, 0.3 x
    # quaternion, either sign of it)
    from sik_ros.tables.seed_table import to_axis_frame, turned
    frame = first_axis(ur5)

    def keys(positions, quats):
        pa, qa = to_axis_frame(frame, positions, quats)
        pa, qa = turned(pa, qa, -np.arctan2(pa[:, 1], pa[:, 0]))
        return np.concatenate([pa, QUATERNION_SCALE * qa], axis=1)

    goal = keys(p[None], quat[None])[0]

    def distance(q):
        k = keys(*ur5.fk_batch(q))
        return np.min([np.linalg.norm(k - np.concatenate([goal[:3], s * goal[3:]]), axis=1)
                       for s in (1, -1)], axis=0)
    radius = np.sort(distance(table.q))[NEIGHBOURS - 1]
    assert distance(starts).max() <= radius + 1e-9


def test_the_goal_key_in_floats_is_the_tables_key_arithmetic(ur5, table):
    """A goal's key, computed in Python floats, is the axis frame and turn the rows get."""
    from sik_ros.tables.seed_table import to_axis_frame, turned
    rng = np.random.default_rng(8)
    for q in rng.uniform(ur5.lower, ur5.upper, (50, 6)):
        p, quat = ur5.fk(q)
        key, azimuth = table.turned_key(p, quat)
        pa, qa = to_axis_frame(first_axis(ur5), p[None], quat[None])
        assert azimuth == pytest.approx(np.arctan2(pa[0, 1], pa[0, 0]), abs=1e-12)
        pa, qa = turned(pa, qa, np.array([-azimuth]))
        np.testing.assert_allclose(key, np.concatenate([pa[0], QUATERNION_SCALE * qa[0]]),
                                   rtol=0, atol=1e-12)


def test_a_small_table_gives_every_row_it_has(ur5, ur5_data):
    """Fewer rows than neighbours: every row is a start once, whatever the goal's quaternion."""
    small = SeedTable.build(ur5, ur5_data, rows=7, seed=2)
    rng = np.random.default_rng(3)
    for q in rng.uniform(ur5.lower, ur5.upper, (10, 6)):
        p, quat = ur5.fk(q)
        starts = small.starts(p, quat, 12)
        assert len(starts) == 7
        assert len(np.unique(starts, axis=0)) == 7


def test_a_goal_whose_quaternion_has_w_near_zero_finds_rows_of_either_sign(ur5, table):
    """A rotation and its negated quaternion are one: a row across w = 0 from the goal is found."""
    p_all, quat_all = ur5.fk_batch(table.q)  # w >= 0
    rows = np.flatnonzero(quat_all[:, 3] < 0.03)[:10]
    assert len(rows) >= 5
    for i in rows:
        x, y, z, w = quat_all[i]
        # the goal turned 4 w [rad] from the row, its quaternion's w on the other side of 0
        starts = table.starts(p_all[i], np.array([x, y, z, -w]), 4)
        np.testing.assert_allclose(starts[0], table.q[i])


def test_a_damaged_or_foreign_seed_table_is_refused(ur5, panda, table, tmp_path):
    """Truncated file, codes that disagree with the manifest, another robot: refused."""
    path = table.save(tmp_path / 'seeds.npz')
    bad = tmp_path / 'truncated.npz'
    bad.write_bytes(path.read_bytes()[:500])
    with pytest.raises(CorruptArtifact):
        SeedTable.load(bad, ur5)
    with np.load(path) as f:
        manifest = str(f['manifest'])
    np.savez(tmp_path / 'short.npz', codes=np.zeros((10, 6), np.uint16), manifest=manifest)
    with pytest.raises(CorruptArtifact, match='disagree'):
        SeedTable.load(tmp_path / 'short.npz', ur5)
    with pytest.raises(ArtifactMismatch):
        SeedTable.load(path, panda)
    with pytest.raises(InvalidArgument):
        SeedTable.build(ur5, None, rows=0)
    # a manifest whose robot is not a robot manifest, or whose limits are not the robot's
    codes = np.zeros((3000, 6), np.uint16)
    for robot in ('x', dict(json.loads(manifest)['robot'], lower=[-100.0] * 6)):
        bad_manifest = dict(json.loads(manifest), robot=robot)
        np.savez(tmp_path / 'odd.npz', codes=codes, manifest=json.dumps(bad_manifest))
        with pytest.raises((CorruptArtifact, ArtifactMismatch)):
            SeedTable.load(tmp_path / 'odd.npz', ur5)


def test_a_bundle_lists_its_seed_table_and_keeps_it_when_a_goal_is_indexed_again(
        ur5_bundle, tmp_path):
    """bundle.json names the seed table; re-adding the pose model keeps it; a bad name fails."""
    out, _ = ur5_bundle
    bundle = tmp_path / 'copy'
    shutil.copytree(out, bundle)
    manifest = json.loads((bundle / 'bundle.json').read_text())
    files = manifest['models']['pose']
    add_to_bundle(bundle, manifest['robot'], 'pose', bundle / files['model'],
                  bundle / files['table'])
    assert json.loads((bundle / 'bundle.json').read_text())['models']['pose'] == files
    assert load_bundle(bundle)[2]['pose'].seeds is not None
    for name in ('', 7):
        broken = json.loads((bundle / 'bundle.json').read_text())
        broken['models']['pose']['seeds'] = name
        (bundle / 'bundle.json').write_text(json.dumps(broken))
        with pytest.raises(CorruptArtifact):
            load_bundle(bundle)


def test_isolated_pose_solutions_from_the_seed_table_or_random_starts(ur5_bundle, ur5):
    """With the seed table or without it (``seed_starts`` 0), FK-verified distinct solutions."""
    from sik_ros import SelectiveIK
    ik = SelectiveIK.load(ur5_bundle[0])
    assert ik.models['pose'].seeds is not None
    rng = np.random.default_rng(12)
    for solver in (ik, ik.with_config(seed_starts=0)):
        for q in rng.uniform(ur5.lower, ur5.upper, (3, 6)):
            p, quat = ur5.fk(q)
            res = solver.solve(p, quat, num_solutions=8)
            assert res.success
            qs = np.array([s.q for s in res.solutions if s.converged])
            reached, _ = ur5.fk_rot(qs)
            assert np.linalg.norm(reached - p, axis=1).max() <= 1e-4
            assert posture_mask(ik.context, qs, 'pose').all()


def test_arms_of_up_to_seven_joints_get_one_by_default(ur5, panda, tmp_path):
    """Six joints or fewer: a large table; seven: a small one; more: none.

    The large one gives isolated branches their starts, the small one the family search's;
    arms of more joints walk their self-motion.
    """
    urdf = tmp_path / 'snake.urdf'
    urdf.write_text(chain_text(8))
    snake = load_robot('snake', urdf=str(urdf), base='base', tip='tip')
    assert snake.dof == 8
    assert default_rows(ur5) == DEFAULT_ROWS
    assert default_rows(panda) == SEARCH_SEED_TABLE_ROWS < DEFAULT_ROWS
    assert default_rows(snake) is None


def test_starts_turn_with_the_goal_about_the_first_axis(ur5, table):
    """A goal turned about the first joint's axis starts from the same rows, joint 1 turned."""
    origin, rot = first_axis(ur5)
    np.testing.assert_allclose(origin[:2], 0.0, atol=1e-12)  # the UR5's: the base's z axis
    np.testing.assert_allclose(rot[:, 2], [0.0, 0.0, 1.0], atol=1e-12)
    q0 = np.array([0.4, -1.1, 1.3, -0.9, 1.2, 0.3])
    p, quat = ur5.fk(q0)
    starts = table.starts(p, quat, 8)
    q1 = q0.copy()
    q1[0] += 1.0
    p1, quat1 = ur5.fk(q1)
    turned = table.starts(p1, quat1, 8)
    step = np.angle(np.exp(1j * (turned - starts)))  # joint 1 may be a whole turn apart
    np.testing.assert_allclose(step[:, 0], 1.0, atol=1e-9)
    np.testing.assert_allclose(step[:, 1:], 0.0, atol=1e-9)
    assert np.all(turned >= ur5.lower) and np.all(turned <= ur5.upper)
    # their tips are the goal's neighbours: 3,000 rows serve every azimuth
    reached, _ = ur5.fk_batch(turned)
    assert np.median(np.linalg.norm(reached - p1, axis=1)) < 0.25


def test_a_first_axis_off_the_base_origin_is_found_and_turns_the_arm():
    """The SO-100's first joint turns it about a line 4.5 cm off the base's z axis."""
    from sik_ros.tables.seed_table import to_axis_frame, turned
    so100 = load_robot('so100')
    frame = first_axis(so100)
    assert frame is not None and abs(frame[0][1]) > 0.04
    q = np.random.default_rng(8).uniform(so100.lower, so100.upper, (20, so100.dof))
    moved = q.copy()
    moved[:, 0] += 0.3
    p, quat = turned(*to_axis_frame(frame, *so100.fk_batch(q)), np.full(20, 0.3))
    p2, quat2 = to_axis_frame(frame, *so100.fk_batch(moved))
    np.testing.assert_allclose(p, p2, atol=1e-9)
    np.testing.assert_allclose(np.abs(np.einsum('ij,ij->i', quat, quat2)), 1.0, atol=1e-9)


def test_a_first_joint_short_of_a_turn_still_gets_its_neighbours(monkeypatch, tmp_path):
    """Rows whose first joint cannot take the goal's azimuth are replaced by farther ones.

    The SO-100's first joint spans 4 rad: the rows nearest a goal in the turned keys that would
    need joint 1 beyond its limits are left out, and the look-up goes further until it has
    its ``neighbours`` rows (all within the limits).
    """
    import sik_ros.tables.seed_table as seed_table
    so100 = load_robot('so100')
    data = collect(so100, tmp_path / 'so100', sampler='uniform', samples=6000, seed=5)
    small = SeedTable.build(so100, data, rows=4000, seed=1)
    rng = np.random.default_rng(6)
    for q in rng.uniform(so100.lower, so100.upper, (20, so100.dof)):
        p, quat = so100.fk(q)
        starts = small.starts(p, quat, 24, 100)
        assert seed_table.START_LEAST <= len(starts) <= 24
        assert np.all(starts >= so100.lower) and np.all(starts <= so100.upper)
        # without the spacing, every one of the neighbours the far-apart starts come from
        monkeypatch.setattr(seed_table, 'START_SPACING', 0.0)
        pool = small.starts(p, quat, 1000, 100)
        monkeypatch.undo()
        assert len(pool) == 100
        assert np.all(pool >= so100.lower) and np.all(pool <= so100.upper)


def test_the_lean_path_answers_as_the_general_stages(ur5_bundle, monkeypatch):
    """Isolated pose goals without seed or obstacles: the same ranked answer either way.

    :mod:`sik_ros.solver.families.isolated` takes the UR5's calls (its joints made non-periodic
    here, so that its own ranking runs, not the general one of 2 pi equivalents); the general
    stages answer the same goals when it is switched off. Every field is equal.
    """
    from sik_ros import SelectiveIK
    import sik_ros.solver.call as call_module
    import sik_ros.solver.families.isolated as isolated
    import sik_ros.solver.pipeline as pipeline
    ik = SelectiveIK.load(ur5_bundle[0])
    monkeypatch.setattr(ik.robot, 'periodic', np.zeros(ik.robot.dof, dtype=bool))
    answered = []
    every_branch = isolated.every_branch

    def spy(*args):
        out = every_branch(*args)
        answered.append(out[0] is not None)
        return out

    monkeypatch.setattr(pipeline, 'every_branch', spy)
    rng = np.random.default_rng(21)
    for q in rng.uniform(ik.robot.lower, ik.robot.upper, (12, ik.robot.dof)):
        p, quat = ik.fk(q)
        for num in (16, 2, 1):
            lean = ik.solve(p, quat, num_solutions=num)
            with monkeypatch.context() as m:
                m.setattr(call_module, 'lean', lambda call: False)
                general = ik.solve(p, quat, num_solutions=num)
            assert (lean.success, lean.timed_out, lean.message) == \
                (general.success, general.timed_out, general.message)
            assert len(lean.solutions) == len(general.solutions)
            for a, b in zip(lean.solutions, general.solutions):
                np.testing.assert_array_equal(a.q, b.q)
                np.testing.assert_array_equal(a.posture_index, b.posture_index)
                assert (a.position_error, a.orientation_error, a.score, a.tier,
                        a.self_collision, a.converged, a.min_obstacle_distance) == \
                    (b.position_error, b.orientation_error, b.score, b.tier,
                     b.self_collision, b.converged, b.min_obstacle_distance)
    assert sum(answered) >= 30  # the lean path answered (exact solutions found)
