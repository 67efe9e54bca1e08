"""sik-reach's map: voxels within the reach, orientations over SO(3), resumable chunks."""

import json

import numpy as np
import pytest

from sik_ros.bundles.sweep_models import sweep_models
from sik_ros.cli import reach
from sik_ros.errors import ArtifactMismatch, CorruptArtifact
from sik_ros.solver import SelectiveIK
from sik_ros.solver.reach_map import (build_reach_map, fibonacci_orientations, load_reach_map,
                                      reach_radius, reach_voxels, ReachSettings)

pytestmark = pytest.mark.e2e  # solve_batch starts worker processes

TINY = ReachSettings(voxel=0.35, orientations=4, num_solutions=2, chunk_goals=64)


def test_orientations_are_unit_and_spread():
    """64 super-Fibonacci quaternions are unit, and no two within 10 degrees of each other."""
    q = fibonacci_orientations(64)
    assert q.shape == (64, 4) and np.allclose(np.linalg.norm(q, axis=1), 1.0)
    dots = np.abs(q @ q.T)[~np.eye(64, dtype=bool)]
    assert 2 * np.degrees(np.arccos(dots.max())) > 10.0


def test_no_configuration_reaches_past_the_radius(ur5):
    """The reach radius bounds the tip's distance from the first joint over random postures."""
    origin, radius = reach_radius(ur5)
    q = np.random.default_rng(0).uniform(ur5.lower, ur5.upper, (500, ur5.dof))
    far = max(np.linalg.norm(ur5.fk(qi)[0] - origin) for qi in q)
    assert 0.0 < far <= radius


def test_map_resumes_from_its_chunks_and_refuses_other_settings(tiny_bundle, tmp_path):
    """A chunk removed is solved again to the same map; other settings are refused."""
    ik = SelectiveIK.load(tiny_bundle)
    path = build_reach_map(ik, tmp_path, TINY, workers=1)
    data = load_reach_map(path)
    centres, _ = reach_voxels(ik.robot, TINY.voxel)
    assert data['success'].shape == (len(centres), 4) and len(centres) > 0
    assert data['success'].any()
    chunks = sorted((tmp_path / 'chunks').glob('*.npz'))
    assert len(chunks) == json.loads((tmp_path / 'manifest.json').read_text())['chunks'] > 1
    chunks[1].unlink()
    again = load_reach_map(build_reach_map(ik, tmp_path, TINY, workers=1))
    assert np.array_equal(again['success'], data['success'])
    assert np.array_equal(again['families'], data['families'])
    with pytest.raises(ArtifactMismatch):
        build_reach_map(ik, tmp_path, ReachSettings(voxel=0.3, orientations=4))
    (tmp_path / 'bad.npz').write_bytes(b'not a zip')
    with pytest.raises(CorruptArtifact):
        load_reach_map(tmp_path / 'bad.npz')


def test_second_arm_map_goals_are_reached_where_solve_reaches_them(ur5, tmp_path):
    """A UR5 map (a table of configurations) marks a goal reached exactly where solve does."""
    ik = SelectiveIK(ur5, sweep_models(ur5, rows=20000))
    settings = ReachSettings(voxel=0.5, orientations=2, num_solutions=2, chunk_goals=64)
    data = load_reach_map(build_reach_map(ik, tmp_path, settings, workers=2))
    assert len(data['centers']) > 0 and data['success'].any()
    for v in range(0, len(data['centers']), 7):
        for k, quat in enumerate(data['orientations']):
            assert ik.solve(data['centers'][v], quat, num_solutions=2).success == \
                data['success'][v, k]


def test_cli_writes_map_and_png(tiny_bundle, tmp_path, run_main):
    """sik-reach --bundle writes reach.npz and reach.png; --orientations 0 is exit 2."""
    out = tmp_path / 'map'
    code, _ = run_main(reach.main, ['--bundle', str(tiny_bundle), '--voxel', '0.4',
                                    '--orientations', '2', '-n', '2', '--out', str(out)])
    assert code == 0
    assert (out / 'reach.png').stat().st_size > 0 and load_reach_map(out / 'reach.npz')
    code, err = run_main(reach.main, ['--bundle', str(tiny_bundle), '--orientations', '0'])
    assert code == 2 and 'orientations' in err
