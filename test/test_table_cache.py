"""The table of configurations in an arm's cache entry: loaded on restart, never if damaged."""

import json
from pathlib import Path
import shutil
from typing import Callable, Dict

import numpy as np
import pytest

from arm_urdfs import chain_text, erd_text
from sik_ros.bundles.cache import write_checksums
from sik_ros.bundles.table_cache import table_folder
from sik_ros.serving.arm_source import prepare_arm, table_solver
from sik_ros.solver import SolverConfig

#: Two arms: the Panda from its URDF (7 joints, a family-search seed table) and a 6-joint chain
#: (isolated pose solutions, a seed table with branch codes).
ARMS = {'panda': (lambda: erd_text('panda'), 'panda_link0', 'panda_hand_tcp'),
        'chain6': (lambda: chain_text(6), 'base', 'tip')}
#: A short sweep: the least rows (the tests need the cache, not a dense table).
SECONDS = 0.05
#: Per arm, the answers of the start that built and cached its table (:func:`built`).
ANSWERS: Dict[str, np.ndarray] = {}


def start(name: str, cache: Path, lines: list):
    """One start of the arm on ``cache``: its Arm and its table's solver (the save waited for)."""
    text, base, tip = ARMS[name]
    arm = prepare_arm(text(), base, tip, str(cache))
    ik = table_solver(arm, SolverConfig(), SECONDS, lines.append)
    if arm.saving is not None:
        arm.saving.join()
    return arm, ik


def exact_answers(ik, seed: int = 5, count: int = 6):
    """The first solution of pose goals (FK of random configurations), each checked exact."""
    robot = ik.robot
    q = np.random.default_rng(seed).uniform(robot.lower, robot.upper, (count, robot.dof))
    assert len(q) == count
    out = []
    for qi in q:
        p, quat = robot.fk(qi)
        res = ik.solve(p, quat, num_solutions=4)
        assert res.success
        best = res.solutions[0]
        placement = robot.pin_placement(best.q)
        assert np.linalg.norm(placement.translation - p) <= 1e-4
        assert np.all(best.q >= robot.lower - 1e-12) and np.all(best.q <= robot.upper + 1e-12)
        out.append(best.q)
    return np.array(out)


@pytest.fixture(scope='module')
def built(tmp_path_factory) -> Dict[str, Path]:
    """Per arm, a cache folder whose entry holds the table of configurations of one start."""
    out = {}
    for name in ARMS:
        cache = tmp_path_factory.mktemp(f'cache_{name}')
        lines = []
        arm, ik = start(name, cache, lines)
        assert arm.table_built == 1 and arm.table_loaded == 0, lines
        assert (table_folder(arm.entry) / 'checksums.json').is_file()
        out[name] = cache
        ANSWERS[name] = exact_answers(ik)
    return out


@pytest.mark.parametrize('name', sorted(ARMS))
def test_a_restart_loads_the_cached_table_and_answers_alike(name, built, tmp_path):
    """A restart loads the table the first start cached (not swept again): the same answers."""
    cache = tmp_path / 'cache'
    shutil.copytree(built[name], cache)
    folder = next(cache.rglob('table'))
    stamp = (folder / 'configurations.npz').stat().st_mtime_ns
    lines = []
    arm, ik = start(name, cache, lines)
    assert (arm.table_built, arm.table_loaded, arm.saving) == (0, 1, None), lines
    assert any('loaded from the cache' in line for line in lines)
    assert (folder / 'configurations.npz').stat().st_mtime_ns == stamp  # not written again
    # the start that swept and cached the table answered so too (a fresh sweep's rows are
    # sized by the time FK takes here, so its table, and its answers, may differ)
    loaded, swept = exact_answers(ik), ANSWERS[name]
    assert loaded.shape == swept.shape and np.allclose(loaded, swept, atol=1e-9)


def _rewrite(folder: Path, file: str, change: Callable[[dict], None]) -> None:
    """Change arrays of an ``.npz`` of the table and write its checksums again.

    No checksum catches the change: the checks of what the file holds must.
    """
    with np.load(folder / file) as f:
        arrays = {k: f[k] for k in f.files}
    change(arrays)
    np.savez(folder / file, **arrays)
    write_checksums(folder)


def _key(folder: Path) -> None:
    manifest = json.loads((folder / 'table.json').read_text())
    manifest['chain_key'] = '0' * 24
    (folder / 'table.json').write_text(json.dumps(manifest))
    write_checksums(folder)


def _truncate(folder: Path) -> None:
    path = folder / 'configurations.npz'
    path.write_bytes(path.read_bytes()[:1000])


def _flip(folder: Path) -> None:
    path = folder / 'seeds.npz'
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))


def _node_child(a: dict) -> None:
    nodes = a['tree_nodes'].copy()
    nodes[0, 1] = 10 ** 6  # the root's children outside the tree
    a['tree_nodes'] = nodes


DAMAGE = {
    'truncated': (_truncate, 'changed since it was written'),
    'bad checksum': (_flip, 'changed since it was written'),
    'another chain key': (_key, 'chain key'),
    'configurations of another shape': (
        lambda f: _rewrite(f, 'configurations.npz',
                           lambda a: a.update(indices=a['indices'][:, :-1].copy())),
        'disagree with its manifest'),
    'reach grid of another shape': (
        lambda f: _rewrite(f, 'configurations.npz',
                           lambda a: a.update(reach=a['reach'][:-1].copy())),
        'reach grid'),
    'a seed tree node outside the tree': (
        lambda f: _rewrite(f, 'seeds.npz', _node_child), 'outside the tree'),
    'no checksums': (lambda f: (f / 'checksums.json').unlink(), 'unfinished'),
}


@pytest.mark.parametrize('damage', sorted(DAMAGE))
@pytest.mark.parametrize('name', sorted(ARMS))
def test_a_damaged_cached_table_is_set_aside_and_built_again(name, damage, built, tmp_path):
    """A damaged cached table is set aside with its reason, never served; swept again, cached anew.

    The table swept again answers exactly.
    """
    cache = tmp_path / 'cache'
    shutil.copytree(built[name], cache)
    folders = list(cache.rglob('table'))
    assert len(folders) == 1
    harm, words = DAMAGE[damage]
    harm(folders[0])
    lines = []
    arm, ik = start(name, cache, lines)
    assert (arm.table_built, arm.table_loaded) == (1, 0), lines
    said = [line for line in lines if 'set aside' in line]
    assert len(said) == 1 and words in said[0], lines
    aside = sorted(arm.entry.path.glob('table.damaged-*'))
    assert len(aside) == 2 and aside[0].is_dir()  # the folder and its reason
    assert words in aside[1].read_text()
    assert len(exact_answers(ik)) == 6
    again = []
    restarted, _ = start(name, cache, again)
    assert (restarted.table_built, restarted.table_loaded) == (0, 1), again


def test_reach_grid_bounds_hold_the_distance_beyond_its_cap():
    """The reach grid's bounds hold the KD-tree's distance, in voxels past its cap too."""
    from scipy.spatial import cKDTree
    from sik_ros.tables.reach_grid import REACH_CAP, ReachGrid
    rng = np.random.default_rng(1)
    centers = rng.uniform(-0.5, 0.5, (3000, 3))
    centers = centers[np.linalg.norm(centers, axis=1) < 0.5]
    tree = cKDTree(centers)
    grid = ReachGrid(tree, centers)
    assert np.isinf(grid.dist).any() and np.isfinite(grid.dist).any()
    points = rng.uniform(-0.9, 0.9, (4000, 3))
    bounds = [(grid.bounds(p), tree.query(p)[0]) for p in points]
    bounds = [(b, d) for b, d in bounds if b is not None]
    assert len(bounds) > 2000 and any(d > REACH_CAP for _, d in bounds)
    for (low, high), d in bounds:
        assert low <= d <= high
