"""Seed tables: dataset configurations by tip pose, the starts of isolated pose solutions."""

import numpy as np
import pytest

from sik_ros.dataset import collect
from sik_ros.errors import ArtifactMismatch, CorruptArtifact, InvalidArgument
from sik_ros.seed_table import default_rows, SeedTable


@pytest.fixture(scope='module')
def ur5_data(ur5, tmp_path_factory):
    """8,000 UR5 configurations drawn uniformly (periodic joints over one turn)."""
    return collect(ur5, tmp_path_factory.mktemp('ds') / 'ur5', sampler='uniform', samples=8000,
                   seed=4)


@pytest.fixture(scope='module')
def table(ur5, ur5_data):
    """A seed table of 3,000 of them."""
    return SeedTable.build(ur5, ur5_data, rows=3000, seed=1)


def test_a_seed_table_keeps_dataset_rows_and_round_trips(ur5, ur5_data, table, tmp_path):
    """Its rows are dataset configurations (to 16-bit precision), the same after save and load."""
    assert len(table) == 3000
    data = np.asarray(ur5_data.q)
    nearest = np.abs(table.q[:, None, :] - data[None, :, :]).max(axis=2).min(axis=1)
    assert nearest.max() < 4 * np.pi / 65535  # one code step over a 4 pi range
    loaded = SeedTable.load(table.save(tmp_path / 'seeds.npz'), ur5)
    np.testing.assert_array_equal(loaded.q, table.q)
    assert loaded.manifest['rows'] == 3000 and loaded.manifest['robot'] == ur5.manifest()


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
    # tips near the goal: among the 200 nearest of 3,000 rows by pose
    tips, _ = ur5.fk_rot(starts)
    all_tips, _ = ur5.fk_rot(table.q)
    assert np.median(np.linalg.norm(tips - p, axis=1)) < np.median(
        np.linalg.norm(all_tips - p, axis=1))


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


def test_only_arms_of_six_joints_or_fewer_get_one_by_default(ur5, panda):
    """Redundant arms walk their self-motion instead: no seed table unless asked for."""
    assert default_rows(ur5) > 0 and default_rows(panda) is None
