"""Many targets on a Ray cluster: a local cluster started here gives the local answers and map.

``sik-reach --ray local`` starts (and stops) a local cluster of its own first; then one local
cluster of two CPUs serves the module's other tests, started by :class:`RayExecutor` itself.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from sik_ros.cli import reach
from sik_ros.errors import InvalidArgument, SikError
from sik_ros.solver import SelectiveIK
from sik_ros.solver.cluster import RayExecutor
from sik_ros.solver.reach_map import build_reach_map, load_reach_map, ReachSettings

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(300)]  # a Ray cluster and its actors

TINY = ReachSettings(voxel=0.35, orientations=4, num_solutions=2, chunk_goals=64)


def test_sik_reach_on_a_local_cluster_is_the_local_map(tiny_bundle, tmp_path):
    """``sik-reach --ray local`` gives the map of local worker processes, goal by goal."""
    ik = SelectiveIK.load(tiny_bundle)
    local = load_reach_map(build_reach_map(ik, tmp_path / 'local', TINY, workers=1))
    assert local['success'].any() and not local['success'].all()
    rc = reach.main(['--bundle', str(tiny_bundle), '--voxel', '0.35', '--orientations', '4',
                     '-n', '2', '--out', str(tmp_path / 'cli'), '--ray', 'local',
                     '--workers', '2'])
    assert rc == 0
    cli = load_reach_map(tmp_path / 'cli' / 'reach.npz')
    for key in ('centers', 'orientations', 'success', 'families', 'reachability'):
        assert np.array_equal(local[key], cli[key]), key
    assert (tmp_path / 'cli' / 'reach.png').stat().st_size > 1000
    import ray
    assert not ray.is_initialized(), 'the CLI ends the session it opened'


@pytest.fixture(scope='module')
def executor():
    """Solver actors on a local Ray cluster of two CPUs, stopped after the module."""
    with RayExecutor(workers=2) as ex:
        yield ex


def same_answers(a, b) -> bool:
    """Whether two lists of results hold the same solutions (joints, families) in order."""
    return len(a) == len(b) and all(
        x.success == y.success and x.num_families == y.num_families
        and len(x.solutions) == len(y.solutions)
        and all(np.array_equal(s.q, t.q) and s.family == t.family and s.tier == t.tier
                for s, t in zip(x.solutions, y.solutions))
        for x, y in zip(a, b))


def test_solve_batch_on_the_cluster_is_solve(executor, tiny_bundle):
    """60 pose and position goals on the cluster: each answer the one solve gives, in order."""
    ik = SelectiveIK.load(tiny_bundle)
    r = ik.robot
    q = np.random.default_rng(7).uniform(r.lower, r.upper, (60, r.dof))
    pos, quat = r.fk_batch(q)
    assert executor.workers == 2
    for orientations in (quat, None):
        here = ik.solve_batch(pos, orientations, num_solutions=4, workers=1)
        there = ik.solve_batch(pos, orientations, num_solutions=4, executor=executor)
        assert same_answers(here, there)
        assert sum(a.success for a in there) >= 50
        first = there[0].solutions[0]
        assert np.isfinite(first.posture_index).all()  # encoded here, as local workers' are


def test_the_map_on_the_cluster_is_the_local_map(executor, tiny_bundle, tmp_path):
    """A reach map built on the cluster through the library is the local one."""
    ik = SelectiveIK.load(tiny_bundle)
    local = load_reach_map(build_reach_map(ik, tmp_path / 'local', TINY, workers=1))
    on_ray = load_reach_map(build_reach_map(ik, tmp_path / 'ray', TINY, executor=executor))
    for key in ('centers', 'orientations', 'success', 'families', 'reachability'):
        assert np.array_equal(local[key], on_ray[key]), key


def test_what_the_cluster_cannot_take_is_refused(executor, tiny_bundle):
    """What the cluster cannot take is refused, saying what is wrong.

    Not an executor, a solver without a bundle, an objective that cannot travel, a second
    executor on a cluster whose CPUs the first one's actors hold.
    """
    ik = SelectiveIK.load(tiny_bundle)
    pos = ik.robot.fk_batch(np.zeros((2, ik.robot.dof)))[0]
    ik.solve_batch(pos[:1], executor=executor)  # its actors hold the cluster's two CPUs
    with pytest.raises(InvalidArgument, match='executor must be a RayExecutor'):
        ik.solve_batch(pos, executor=object())
    with pytest.raises(InvalidArgument, match='loaded from a bundle'):
        list(executor.solve_chunks(SimpleNamespace(bundle=None), [], {}))
    with pytest.raises(InvalidArgument, match='pickled'):
        ik.solve_batch(pos, executor=executor, objective=lambda q: q.sum(axis=1))
    with pytest.raises(SikError, match='no free CPU'):
        RayExecutor('auto')
