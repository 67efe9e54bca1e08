"""Dataset collection (Algorithm 1), manifests, and refusal of damaged datasets."""

import json
import math

import numpy as np
import pytest

from sik_ros.errors import (ArtifactExists, ArtifactMismatch, CorruptArtifact,
                            InvalidArgument)
from sik_ros.kinematics.robots import load_robot
from sik_ros.tables.dataset import collect, Dataset, grid_count, grid_values


def test_panda_grid_count_is_the_papers(panda):
    """The Panda's 30-degree grid has exactly 12*7*12*6*12*8*12 = 6,967,296 configurations."""
    counts = [len(v) for v in grid_values(panda.lower, panda.upper, 30.0)]
    assert counts == [12, 7, 12, 6, 12, 8, 12]
    assert grid_count(panda.lower, panda.upper, 30.0) == 6_967_296


def test_grid_count_formula():
    """Each joint contributes floor(range / step) + 1 values, from its lower limit."""
    lower = np.radians([-10.0, 0.0])
    upper = np.radians([10.0, 45.0])
    values = grid_values(lower, upper, 10.0)
    assert [len(v) for v in values] == [3, 5]
    np.testing.assert_allclose(np.degrees(values[1]), [0, 10, 20, 30, 40])
    assert all(v[-1] <= u + 1e-12 for v, u in zip(values, upper))


@pytest.mark.parametrize('interval', [0.0, -5.0, math.nan, 400.0])
def test_bad_interval_is_refused(panda, interval):
    """A non-positive interval or one larger than a joint's range is refused."""
    with pytest.raises(InvalidArgument, match='interval'):
        grid_values(panda.lower, panda.upper, interval)


def test_grid_rows_match_fk(panda, grid90):
    """Every row's position and orientation equal FK of its joints; rows cover the grid."""
    assert len(grid90) == grid_count(panda.lower, panda.upper, 90.0) == 4608
    rows = np.random.default_rng(0).choice(len(grid90), 300, replace=False)
    pos, quat = panda.fk_batch(np.asarray(grid90.q[rows]))
    np.testing.assert_allclose(pos, grid90.position[rows], atol=1e-9)
    np.testing.assert_allclose(np.abs((quat * grid90.quaternion[rows]).sum(1)), 1.0, atol=1e-9)
    assert len(np.unique(np.asarray(grid90.q), axis=0)) == len(grid90)


def test_manifest_round_trip(panda, grid90):
    """The manifest records robot, URDF hash, frames, limits, sampler, count and versions."""
    m = Dataset.load(grid90.path, panda).manifest
    assert m['robot'] == panda.manifest()
    assert m['sampler'] == 'grid' and m['params'] == {'interval_deg': 90.0}
    assert m['count'] == 4608 and 'pinocchio' in m['versions']
    assert (grid90.path / 'stats.txt').read_text().startswith('sik_ros dataset: panda')


def test_uniform_sampler_is_seeded_and_within_limits(panda, uniform_small, tmp_path):
    """The uniform sampler respects the limits and is reproducible for a seed."""
    q = np.asarray(uniform_small.q)
    assert np.all(q >= panda.lower) and np.all(q <= panda.upper)
    again = collect(panda, tmp_path / 'again', sampler='uniform', samples=6000, seed=3)
    np.testing.assert_array_equal(np.asarray(again.q), q)


def test_truncated_array_is_refused(panda, grid90, tmp_path):
    """A dataset whose array file was cut short is refused with CorruptArtifact."""
    ds = collect(panda, tmp_path / 'cut', interval_deg=90.0)
    f = ds.path / 'position.npy'
    data = f.read_bytes()
    f.write_bytes(data[: len(data) // 2])
    with pytest.raises(CorruptArtifact, match='position.npy'):
        Dataset.load(ds.path, panda)


def test_missing_manifest_is_refused(panda, tmp_path):
    """A directory without a manifest does not look like a complete dataset."""
    (tmp_path / 'q.npy').write_bytes(b'')
    with pytest.raises(CorruptArtifact, match='manifest.json'):
        Dataset.load(tmp_path, panda)


def test_dataset_of_another_robot_is_refused(grid90):
    """A dataset collected for another tip frame is refused with ArtifactMismatch."""
    other = load_robot('panda', None, 'panda_link0', 'panda_link8')
    with pytest.raises(ArtifactMismatch, match='tip_frame'):
        Dataset.load(grid90.path, other)


def test_manifest_count_mismatch_is_refused(panda, tmp_path):
    """A manifest that disagrees with its arrays is refused."""
    ds = collect(panda, tmp_path / 'ds', interval_deg=90.0)
    m = json.loads((ds.path / 'manifest.json').read_text())
    m['count'] += 1
    (ds.path / 'manifest.json').write_text(json.dumps(m))
    with pytest.raises(CorruptArtifact, match='shape'):
        Dataset.load(ds.path, panda)


def test_existing_output_is_refused_unless_forced(panda, tmp_path):
    """An existing output directory is refused without force and replaced with it."""
    out = tmp_path / 'ds'
    out.mkdir()
    with pytest.raises(ArtifactExists, match='--force'):
        collect(panda, out, interval_deg=90.0)
    assert len(collect(panda, out, interval_deg=90.0, force=True)) == 4608


def test_interrupted_collection_leaves_nothing(panda, tmp_path):
    """An exception mid-collection leaves no directory under the final name, nor a partial."""
    def boom(_):
        raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        collect(panda, tmp_path / 'ds', interval_deg=90.0, progress=boom, chunk=512)
    assert list(tmp_path.iterdir()) == []
