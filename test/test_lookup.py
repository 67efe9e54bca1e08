"""The paper's protocol in sik-eval: which indices the look-up gives, and that all count."""

import numpy as np
import pytest

from sik_ros.eval.lookup import lookup_rows, MIN_INDICES, pose_lookup
from sik_ros.solver import SelectiveIK

pytestmark = pytest.mark.slow


def cells_by_distance(table, target):
    """The table's cells, nearest centre first (ties by cell number)."""
    return np.argsort(np.linalg.norm(table.centers - target, axis=1), kind='stable')


def test_the_look_up_takes_the_nearest_cells_until_ten_indices(tiny_bundle):
    """As few nearest cells as give ten indices, every index they hold for a position goal."""
    ik = SelectiveIK.load(tiny_bundle)
    table = ik.models['position'].table
    q = np.random.default_rng(3).uniform(ik.robot.lower, ik.robot.upper, (6, ik.robot.dof))
    targets, _ = ik.robot.fk_batch(q)
    assert len(targets) == 6
    for p in targets:
        rows = lookup_rows(table, p)
        assert len(rows) >= MIN_INDICES
        cell_of_row = np.searchsorted(table.offsets, rows, side='right') - 1
        order = cells_by_distance(table, p)
        used = len(set(cell_of_row.tolist()))
        assert set(cell_of_row.tolist()) <= set(order[:used].tolist()) | set(
            order[used:used + 1].tolist())  # a tie at the last cell's distance
        held = [r for c in order[:used] for r in range(table.offsets[c], table.offsets[c + 1])
                if table.realised is None or table.realised[r]]
        assert len(rows) == len(held)
        fewer = table.rows_near(p, used - 1) if used > 1 else np.empty(0)
        assert len(fewer) < MIN_INDICES


def test_the_pose_look_up_decodes_ten_rows_and_measures_them_by_pinocchio(tiny_bundle):
    """Ten rows per pose target, every one counted: the mean of its own FK errors."""
    from sik_ros.solver.codec import decode
    from sik_ros.solver.context import Goal
    from scipy.spatial.transform import Rotation
    ik = SelectiveIK.load(tiny_bundle)
    assert 'pose' in ik.goals
    q = np.random.default_rng(4).uniform(ik.robot.lower, ik.robot.upper, (3, ik.robot.dof))
    goals = [ik.robot.pin_placement(qi) for qi in q]
    pos = np.array([g.translation for g in goals])
    rot = np.array([g.rotation for g in goals])
    look = pose_lookup(ik, pos, rot, count=10)
    assert list(look.count) == [10, 10, 10]
    table = ik.models['pose'].table
    for i, g in enumerate(goals):
        quat = Rotation.from_matrix(g.rotation).as_quat()
        rows = table.oriented_rows(g.translation, quat, 10, max(ik.config.oriented_cells, 10))
        sols = decode(ik.context, Goal(g.translation, g.rotation), table.indices[rows])
        reached = [ik.robot.pin_placement(s) for s in sols]
        dist = np.mean([np.linalg.norm(r.translation - g.translation) for r in reached])
        angle = np.mean([Rotation.from_matrix(g.rotation.T @ r.rotation).magnitude()
                         for r in reached])
        assert look.distance[i] == pytest.approx(dist, rel=1e-6, abs=1e-9)
        assert look.angle[i] == pytest.approx(angle, rel=1e-5, abs=1e-7)
