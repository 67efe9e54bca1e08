"""Index tables: distinct indices per cell, files checked on load, sik-index end to end."""

import subprocess
import sys

import numpy as np
import pytest
from served import check_served

from sik_ros.defaults import TableConfig
from sik_ros.errors import ArtifactMismatch, CorruptArtifact
from sik_ros.kinematics.robots import load_robot
from sik_ros.tables.index_table import IndexTable
from sik_ros.tables.point_sets import (farthest_point_subset, GRAM_ROWS, pairwise_distances,
                                       SAME_DISTANCE)


def small_table(cell=0.1, dedup=0.5, max_per_cell=4):
    """A table built from hand-made indices at known positions."""
    pos = np.array([[0.01, 0.01, 0.01]] * 5 + [[0.55, 0.01, 0.01]] * 2)
    z = np.array([[0.0], [0.1], [1.0], [2.0], [3.0], [5.0], [5.05]])
    return IndexTable.build(z, pos, TableConfig(cell, dedup, max_per_cell),
                            {'robot': {'robot': 'x'}, 'model': {'m': 1}})


def test_near_duplicates_are_dropped_and_cells_capped():
    """Indices closer than the dedup step count once; a cell keeps at most max_per_cell."""
    table = small_table()
    assert len(table) == 2
    first = sorted(table.indices[table.offsets[0]:table.offsets[1], 0].tolist())
    second = table.indices[table.offsets[1]:table.offsets[2], 0].tolist()
    assert len(first) == 4 and 3.0 in first and 0.0 in first
    assert len(second) == 1


def test_candidates_come_from_the_nearest_cells():
    """A query returns the indices of the cells nearest the position."""
    table = small_table()
    near_second = table.candidates(np.array([0.56, 0.0, 0.0]), k_cells=1)
    assert near_second.shape == (1, 1) and abs(near_second[0, 0] - 5.0) < 0.1


def test_farthest_point_subset_spreads_out():
    """Farthest-point sampling picks the extremes of a line of points first."""
    pts = np.linspace(0, 1, 11)[:, None]
    chosen = farthest_point_subset(pts, 3)
    assert sorted(pts[chosen, 0].tolist()) == [0.0, 0.5, 1.0]


def test_farthest_point_subset_with_a_spacing_stops_at_one_row_per_cluster():
    """With ``spacing``, no row within it of a chosen one is taken (past ``at_least`` rows)."""
    rng = np.random.default_rng(0)
    centres = np.array([[0.0, 0.0], [5.0, 0.0], [0.0, 5.0]])
    pts = np.repeat(centres, 20, axis=0) + rng.normal(0, 0.05, (60, 2))
    chosen = farthest_point_subset(pts, 10, spacing=1.0)
    assert sorted(chosen // 20) == [0, 1, 2]  # one per cluster, then every row is near one
    assert len(farthest_point_subset(pts, 10, spacing=1.0, at_least=5)) == 5
    np.testing.assert_array_equal(farthest_point_subset(pts, 10, spacing=1.0, at_least=5)[:3],
                                  chosen)
    # equal rows are never taken twice, even short of ``at_least``
    assert len(farthest_point_subset(np.repeat(centres, 2, axis=0), 6, spacing=1.0,
                                     at_least=6)) == 3
    assert len(farthest_point_subset(pts, 10)) == 10  # no spacing: as many as asked
    # nothing to choose from (a seed table none of whose rows fits a goal's azimuth)
    assert len(farthest_point_subset(np.empty((0, 2)), 10, spacing=1.0, at_least=5)) == 0
    assert len(farthest_point_subset(pts, 0, spacing=1.0)) == 0


def test_save_load_round_trip(tmp_path):
    """A saved table loads back with the same cells and indices (float16 storage)."""
    table = small_table()
    path = table.save(tmp_path / 't.npz')
    back = IndexTable.load(path, {'robot': 'x'}, {'m': 1})
    np.testing.assert_allclose(back.indices, table.indices, atol=1e-2)
    np.testing.assert_array_equal(back.offsets, table.offsets)


def oriented_table():
    """A one-cell table whose indices 0..3 came from rows turned 0, 30, 60, 90 deg about z."""
    from scipy.spatial.transform import Rotation
    angles = np.radians([0.0, 30.0, 60.0, 90.0])
    quat = Rotation.from_euler('z', angles[:, None]).as_quat()
    pos = np.full((4, 3), 0.01)
    z = np.arange(4.0)[:, None]
    return IndexTable.build(z, pos, TableConfig(0.1, 0.5, 8),
                            {'robot': {'robot': 'x'}, 'model': {'m': 1}}, quat), quat


def test_oriented_candidates_are_the_nearest_in_orientation(tmp_path):
    """Each index keeps its row's orientation, through a save and a load (8-bit storage).

    A pose query returns the indices whose rows were turned nearest the goal, nearest first.
    """
    from scipy.spatial.transform import Rotation
    table, quat = oriented_table()
    back = IndexTable.load(table.save(tmp_path / 'o.npz'))
    for t in (table, back):
        order = np.argsort(t.indices[:, 0])
        angle = np.degrees(2 * np.arccos(np.clip(np.abs(
            np.sum(t.orientations[order] * quat, axis=1)), 0, 1)))
        assert angle.max() < 1.5
        goal = Rotation.from_euler('z', 70, degrees=True).as_quat()
        picked = t.oriented_candidates(np.array([0.02, 0.0, 0.0]), goal, 2)
        assert picked[:, 0].tolist() == [2.0, 3.0]


def test_a_table_without_orientations_says_so(tmp_path):
    """Asking a position-only table for oriented candidates names the fix.

    A file whose orientations disagree with its manifest is refused.
    """
    from sik_ros.errors import InvalidArgument
    with pytest.raises(InvalidArgument, match='orientations'):
        small_table().oriented_candidates(np.zeros(3), np.array([0, 0, 0, 1.0]), 2)
    table, _ = oriented_table()
    table.manifest = dict(table.manifest, orientations=False)
    path = table.save(tmp_path / 'bad.npz')
    with pytest.raises(CorruptArtifact, match='orientations'):
        IndexTable.load(path)


def test_decoded_postures_are_the_decoder_at_the_cell_centres(tiny_bundle, tmp_path):
    """A position table's decoded postures are its indices decoded at their cells' centres.

    They stay within 8 bits of the joint range through a save and a load, and are checked on
    load.
    """
    import json
    import torch
    from sik_ros.errors import InvalidArgument
    from sik_ros.learning.checkpoints import load_checkpoint, model_from_checkpoint
    from sik_ros.learning.indexing import decode_postures
    panda = load_robot('panda')
    table = IndexTable.load(tiny_bundle / 'sik_position_table.npz')
    assert table.postures is not None and table.postures.shape == (len(table.indices), 7)
    model, mcfg, norm = model_from_checkpoint(load_checkpoint(tiny_bundle / 'sik_position.pt'))
    rows = np.array([0, len(table.indices) // 2, len(table.indices) - 1])
    with torch.no_grad():
        goal = norm.goal_to_net(torch.from_numpy(table.cell_centers(rows).astype(np.float32)))
        q = norm.q_from_net(model.decode(goal, torch.from_numpy(table.indices[rows])))
    q = np.clip(q.double().numpy(), panda.lower, panda.upper)
    step = (panda.upper - panda.lower) / 255
    assert np.all(np.abs(table.postures[rows] - q) <= step / 2 + 1e-5)
    fresh = decode_postures(model, mcfg, norm, table, panda.lower, panda.upper)
    assert np.all(np.abs(fresh - table.postures) <= step / 2 + 1e-5)
    pose_model, pose_cfg, pose_norm = model_from_checkpoint(
        load_checkpoint(tiny_bundle / 'sik_pose.pt'))
    with pytest.raises(InvalidArgument, match='position-goal'):
        decode_postures(pose_model, pose_cfg, pose_norm, table, panda.lower, panda.upper)
    bad = table.with_postures(fresh, panda.lower, panda.upper)
    bad.manifest = dict(bad.manifest, postures={'lower': [0.0], 'upper': [1.0]})
    with pytest.raises(CorruptArtifact, match='postures'):
        IndexTable.load(bad.save(tmp_path / 'bad.npz'))
    none = IndexTable(table.centers, table.offsets, table.indices,
                      json.loads(json.dumps(bad.manifest)))
    with pytest.raises(CorruptArtifact, match='postures'):
        IndexTable.load(none.save(tmp_path / 'none.npz'))


def test_mismatched_or_corrupt_table_is_refused(tmp_path):
    """A table of another robot or model, or a damaged file, is refused."""
    path = small_table().save(tmp_path / 't.npz')
    with pytest.raises(ArtifactMismatch, match='robot'):
        IndexTable.load(path, {'robot': 'panda'})
    with pytest.raises(ArtifactMismatch, match='model'):
        IndexTable.load(path, None, {'m': 2})
    path.write_bytes(path.read_bytes()[:200])
    with pytest.raises(CorruptArtifact):
        IndexTable.load(path)


@pytest.mark.e2e
def test_sik_index_cli_builds_a_bundle(tiny_bundle, uniform_small, tmp_path, run_main):
    """sik-index encodes a dataset with a trained model and adds model and table to a bundle.

    The build runs sik-index as a process; its two refusals (exit 2, the reason on stderr) call
    its ``main`` in this process.
    """
    from sik_ros.cli.index import main
    from sik_ros.solver import SelectiveIK
    model = tiny_bundle / 'sik_position.pt'
    r = subprocess.run([sys.executable, '-m', 'sik_ros.cli.index', '--model', str(model),
                        '--dataset', str(uniform_small.path), '--out', str(tmp_path / 't.npz'),
                        '--bundle', str(tmp_path / 'b'), '--quiet'],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    ik = SelectiveIK.load(tmp_path / 'b')
    assert ik.goals == ['position']
    robot = load_robot('panda')
    target = robot.fk_batch(np.asarray(uniform_small.q[:1]))[0][0]
    assert check_served(robot, ik.solve(target, num_solutions=2), target) >= 1
    code, err = run_main(main, ['--model', str(model), '--dataset', str(uniform_small.path),
                                '--out', str(tmp_path / 't.npz'), '--quiet'])
    assert code == 2 and '--force' in err, err
    code, err = run_main(main, ['--model', str(tiny_bundle / 'sik_pose.pt'), '--dataset',
                                str(uniform_small.path), '--out', str(tmp_path / 'p.npz'),
                                '--postures', '--quiet'])
    assert code == 2 and 'position-goal model' in err, err
    assert not (tmp_path / 'p.npz').exists()


def test_within_the_data_agrees_with_the_distance_and_mostly_skips_the_tree(monkeypatch):
    """``within`` answers as the distance to the nearest cell centre does, on and off the grid.

    Inside the workspace the reach grid answers most questions without the KD-tree.
    """
    rng = np.random.default_rng(2)
    pos = rng.uniform(-0.6, 0.6, (4000, 3))
    pos = pos[np.linalg.norm(pos, axis=1) < 0.6]  # a ball of data, 0.6 m across each way
    table = IndexTable.build(rng.normal(size=(len(pos), 1)), pos, TableConfig(0.05, 0.05, 4),
                             {'robot': {'robot': 'x'}, 'model': {'m': 1}})
    assert table.reach.dist is not None
    points = np.concatenate([rng.uniform(-1.5, 1.5, (3000, 3)),      # off the grid too
                             rng.uniform(-0.4, 0.4, (1000, 3))])     # inside
    for p in points:
        for d in (0.02, 0.15, 0.4):
            assert table.within(p, d) == (table.distance_to_data(p) <= d)
    queries = []
    real = table.distance_to_data  # counted, its answers kept: the grid's are checked
    monkeypatch.setattr(table, 'distance_to_data', lambda p: queries.append(p) or real(p))
    inside = [table.within(p, 0.15) for p in points[3000:]]
    assert len(inside) == 1000 and all(inside)
    assert len(queries) < 100  # of 1,000 inside the ball


def test_pairwise_distances_are_scipys_and_zero_between_equal_rows():
    """The matrix-product distances match cdist to 1e-9, and about 0 for equal rows."""
    from scipy.spatial.distance import cdist
    rng = np.random.default_rng(5)
    a = rng.uniform(-3, 3, (60, 12))
    a[7] = a[3]
    b = rng.uniform(-3, 3, (9, 12))
    # rounding: relative 1e-9 apart, within SAME_DISTANCE of 0 between equal rows
    apart = cdist(a, a) > 1e-3
    np.testing.assert_allclose(pairwise_distances(a)[apart], cdist(a, a)[apart], rtol=1e-9)
    np.testing.assert_allclose(pairwise_distances(a), cdist(a, a), atol=SAME_DISTANCE)
    np.testing.assert_allclose(pairwise_distances(a, b), cdist(a, b), rtol=1e-9)
    d = pairwise_distances(a)
    assert d[3, 7] < SAME_DISTANCE and d[7, 3] < SAME_DISTANCE
    assert np.all(np.diag(d) < SAME_DISTANCE)
    big = rng.uniform(-3, 3, (GRAM_ROWS + 1, 3))
    np.testing.assert_array_equal(pairwise_distances(big), cdist(big, big))


def scattered_table(seed=0, cells=3000):
    """A table of one index per row at random positions in a 1.2 m box (many cells)."""
    rng = np.random.default_rng(seed)
    pos = rng.uniform(-0.6, 0.6, (cells, 3))
    z = rng.standard_normal((cells, 2))
    quat = rng.standard_normal((cells, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    return IndexTable.build(z, pos, TableConfig(0.05, 0.01, 4), {'robot': {}, 'model': {}},
                            quaternion=quat)


def test_the_grid_finds_the_kd_trees_nearest_cells():
    """The compiled look-up returns the KD-tree's cells, nearest first.

    Inside the data and far off it (where the KD-tree answers).
    """
    table = scattered_table()
    rng = np.random.default_rng(1)
    for point in rng.uniform(-1.5, 1.5, (400, 3)):
        for k in (1, 8, 27):
            _, cells = table.tree.query(point, k=k)
            cells = np.atleast_1d(cells)
            expected = np.concatenate([np.arange(table.offsets[c], table.offsets[c + 1])
                                       for c in cells])
            assert np.array_equal(table.rows_near(point, k), expected)


def test_best_oriented_rows_are_numpys_choice():
    """The rows nearest a quaternion, nearest first, as a sort of |q . goal| picks them."""
    table = scattered_table(seed=2)
    rng = np.random.default_rng(3)
    for point, quat in zip(rng.uniform(-0.5, 0.5, (100, 3)), rng.standard_normal((100, 4))):
        quat /= np.linalg.norm(quat)
        rows = table.rows_near(point, 27)
        closeness = np.abs(table.orientations[rows].astype(float) @ quat)
        picked = table.oriented_rows(point, quat, 8, 27)
        assert len(picked) == min(8, len(rows))
        assert np.allclose(np.sort(closeness)[::-1][:len(picked)],
                           np.abs(table.orientations[picked].astype(float) @ quat), atol=1e-6)
