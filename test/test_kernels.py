"""Compiled kernels: refinement row by row, its stopping rules, and the small network calls."""

import time

import numpy as np
import pytest

from sik_ros.deadline import Deadline
from sik_ros.kernels.dls import CONVERGED, PRUNED, UNTOUCHED
from sik_ros.solver import SelectiveIK
from sik_ros.solver.context import Goal
from sik_ros.solver.refine import errors, refine


@pytest.fixture(scope='module')
def bundled():
    """The bundled Panda solver (its networks, its chain)."""
    return SelectiveIK.load('panda')


def _refine(ik, q, pos, rot, **kw):
    """The kernel's answer through :func:`sik_ros.solver.refine.refine`."""
    return refine(ik.context, q, Goal(pos, rot), **kw)


def _target(robot, seed):
    """A configuration in the middle half of the joint ranges and its tip pose."""
    mid, half = (robot.lower + robot.upper) / 2, (robot.upper - robot.lower) / 4
    q = np.random.default_rng(seed).uniform(mid - half, mid + half, (1, robot.dof))
    p, r = robot.fk_rot(q)
    return q[0], p[0], r[0]


def test_refined_rows_reach_the_goal_within_the_limits(bundled):
    """Rows started near a pose end within the tolerances by FK, inside the joint limits."""
    robot = bundled.robot
    q_goal, p, r = _target(robot, 0)
    starts = np.clip(q_goal + np.random.default_rng(1).normal(0, 0.05, (6, robot.dof)),
                     robot.lower, robot.upper)
    out = _refine(bundled, starts, p, r)
    perr, oerr = errors(bundled.context, out.q, Goal(p, r))
    np.testing.assert_allclose(out.perr, perr, atol=1e-12)
    np.testing.assert_allclose(out.oerr, oerr, atol=1e-7)  # arccos there: 1e-8 near 0
    assert (perr <= 1e-4).all() and (oerr <= 1e-3).all()
    assert (out.q >= robot.lower).all() and (out.q <= robot.upper).all()
    assert not out.cut_short


def test_enough_stops_after_the_first_exact_rows(bundled):
    """With ``enough=1`` the rows after the first exact one are returned as they started."""
    from sik_ros.kernels import refine_rows  # noqa: F401 (the kernel behind refine)
    robot = bundled.robot
    q_goal, p, r = _target(robot, 2)
    starts = np.stack([q_goal + 0.05, q_goal - 0.05, q_goal + 0.1])
    starts = np.clip(starts, robot.lower, robot.upper)
    out = _refine(bundled, starts, p, r, enough=1)
    assert out.perr[0] <= 1e-4 and out.oerr[0] <= 1e-3
    np.testing.assert_array_equal(out.q[1:], starts[1:])
    # their errors are those of the starts
    start_perr = errors(bundled.context, starts[1:], Goal(p, r))[0]
    np.testing.assert_allclose(out.perr[1:], start_perr, atol=1e-12)


def test_a_past_deadline_leaves_every_row_as_it_started(bundled):
    """A deadline already past: no iteration runs, the call says it was cut short."""
    robot = bundled.robot
    q_goal, p, r = _target(robot, 3)
    starts = np.clip(q_goal + 0.3, robot.lower, robot.upper)[None]
    out = _refine(bundled, starts, p, r, deadline=Deadline(time.perf_counter() - 1.0))
    assert out.cut_short
    np.testing.assert_array_equal(out.q, starts)


def test_a_row_heading_for_an_earlier_solution_is_pruned(bundled):
    """With ``prune`` a second start near the first one's solution stops at a prune step."""
    from sik_ros.kernels import refine_rows
    from sik_ros.kernels.dls import INTS, REALS
    robot, cfg = bundled.robot, bundled.config
    q_goal, p, r = _target(robot, 4)
    start = np.clip(q_goal + 0.02, robot.lower, robot.upper)
    # the second start far from the goal but within the prune radius of the first's solution
    q = np.ascontiguousarray(np.stack([start, np.clip(q_goal + 0.05, robot.lower,
                                                      robot.upper)]))
    q[1] += np.where(np.arange(robot.dof) == 0, 0.08, 0.0)
    settings = dict(position_tolerance=1e-12, orientation_tolerance=1e-12, damping2=1e-6,
                    max_step=1e-3, stall_ratio=0.7, prune_radius=1.0, distinct_threshold=0.5,
                    deadline=np.inf, orientation_weight=0.1, converge_factor=0.5,
                    give_up_factor=10.0, iterations=12, stall_window=0,
                    stall_after=0, give_up_after=100, enough=0, prune=1, roll_free=0, pose=1)
    perr, oerr, status = np.empty(2), np.empty(2), np.empty(2, dtype=np.int8)
    q_in = q.copy()
    refine_rows(robot.frames, robot.lower, robot.upper, robot.periodic, q_in, p, r,
                np.array([settings[k] for k in REALS], dtype=float),
                np.array([settings[k] for k in INTS] + list(cfg.prune_at), dtype=np.int64),
                perr, oerr, status)
    # tiny steps never reach 1e-12: the first row runs out, the second meets it at step 3
    assert status[0] not in (UNTOUCHED, PRUNED, CONVERGED)
    assert status[1] == PRUNED


def test_small_network_calls_match_numpy(bundled):
    """The compiled network (a few rows) equals the NumPy matrix products to float32 rounding."""
    from sik_ros.solver.codec import _twins, NumpyMLP
    for gm in bundled.models.values():
        for net in _twins(gm.model):
            width = net.layers[0][0].shape[0]
            x = np.random.default_rng(5).normal(size=(3, width)).astype(np.float32)
            plain = NumpyMLP.__call__(NumpyMLP(net.layers), np.repeat(x, 3, axis=0))[::3]
            np.testing.assert_allclose(net(x), plain, rtol=1e-4, atol=1e-5)


def test_cache_folder_falls_back_to_a_private_temporary_one(monkeypatch, tmp_path):
    """With the package's folder and the user cache read-only, numba caches in the temp dir.

    In a folder private to the user; when that name is taken by a folder others can write,
    the kernels are not cached on disk at all.
    """
    import os
    import tempfile
    from numba.core import config
    from sik_ros.kernels import _cache
    monkeypatch.setattr(config, 'CACHE_DIR', '')
    assert _cache._configure() and config.CACHE_DIR == ''  # writable here: numba's own choice
    monkeypatch.setattr(_cache, '_writable', lambda folder: False)
    monkeypatch.setattr(tempfile, 'gettempdir', lambda: str(tmp_path))
    assert _cache._configure()
    assert config.CACHE_DIR == str(tmp_path / f'sik_ros-numba-{os.getuid()}')
    monkeypatch.setattr(config, 'CACHE_DIR', '')
    os.chmod(tmp_path / f'sik_ros-numba-{os.getuid()}', 0o777)  # another could write it
    assert not _cache._configure() and config.CACHE_DIR == ''


def test_last_joint_alignment_is_the_best_turn(bundled):
    """The closed-form turn of the last joint is the best one, within the limits.

    No other angle of a sweep over its range brings the tip nearer the goal rotation.
    """
    from sik_ros.solver.candidates import align_last_joint
    robot = bundled.robot
    rng = np.random.default_rng(4)
    q = rng.uniform(robot.lower, robot.upper, (20, robot.dof))
    goal = robot.fk_rot(rng.uniform(robot.lower, robot.upper, (1, robot.dof)))[1][0]
    aligned = align_last_joint(bundled.context, q, goal)
    assert np.array_equal(aligned[:, :-1], q[:, :-1])
    assert np.all((aligned[:, -1] >= robot.lower[-1]) & (aligned[:, -1] <= robot.upper[-1]))

    def angle(rows):
        r = robot.fk_rot(rows)[1]
        cos = (np.trace(goal @ r.transpose(0, 2, 1), axis1=1, axis2=2) - 1) / 2
        return np.arccos(np.clip(cos, -1, 1))

    best = angle(aligned)
    for t in np.linspace(robot.lower[-1], robot.upper[-1], 60):
        swept = aligned.copy()
        swept[:, -1] = t
        assert np.all(best <= angle(swept) + 1e-9)


def test_null_directions_are_the_svds_up_to_sign(bundled):
    """The minors' null vectors of 6 x 7 Jacobians are the SVD's, unit, up to sign.

    ``null_vector7``, the one formula (the walk, the family traces and the family search call
    it), row by row. A singular Jacobian (a column repeated) is reported, for the caller's SVD.
    """
    from sik_ros.kernels.chain import null_directions, null_vector7
    robot = bundled.robot
    q = np.random.default_rng(5).uniform(robot.lower, robot.upper, (50, robot.dof))
    _, _, jac = robot.jacobian_batch(q)
    out = np.empty(q.shape)
    assert null_directions(jac, out).all()
    reference = np.linalg.svd(jac)[2][:, -1]
    assert np.allclose(np.abs(np.sum(out * reference, axis=1)), 1.0, atol=1e-9)
    assert np.allclose(np.einsum('kij,kj->ki', jac, out), 0.0, atol=1e-9)
    one = np.empty(7)
    assert null_vector7(np.ascontiguousarray(jac[3]), np.empty((6, 6)), one)
    np.testing.assert_array_equal(one, out[3])
    singular = jac[:2].copy()
    singular[:, :, 1] = singular[:, :, 0]
    singular[:, :, 2] = singular[:, :, 0]
    assert not null_directions(singular, np.empty((2, 7))).any()


def test_kd_tree_finds_the_exact_nearest_rows_for_one_key_or_two():
    """The k nearest rows are scipy's exact ones; with a second key, the union's nearest.

    A column every point shares (the seed table's y = 0) is left out of the tree and its
    distance added back; with ``eps`` every row returned is within ``1 + eps`` of the k-th.
    """
    from scipy.spatial import cKDTree

    from sik_ros.kernels.kdtree import KDTree
    rng = np.random.default_rng(3)
    points = rng.normal(size=(20000, 7)).astype(np.float32).astype(np.float64)
    points[:, 1] = 0.25
    tree, reference = KDTree(points, 16), cKDTree(points)
    assert list(tree.columns) == [0, 2, 3, 4, 5, 6]
    for key in rng.normal(size=(40, 7)) * 0.7:
        rows, dist = tree.nearest(key, 30)
        d_ref, r_ref = reference.query(key, k=30)
        np.testing.assert_array_equal(tree.order[rows], r_ref)
        np.testing.assert_allclose(dist, d_ref, rtol=0, atol=1e-12)
        other = np.concatenate([key[:3], -key[3:]])
        rows, dist = tree.nearest(key, 30, other=other)
        d_other, r_other = reference.query(other, k=30)
        both = np.concatenate([d_ref, d_other])
        order = np.argsort(both, kind='stable')
        union = np.concatenate([r_ref, r_other])[order]
        union = union[np.sort(np.unique(union, return_index=True)[1])][:30]
        np.testing.assert_array_equal(tree.order[rows], union)
        rows, dist = tree.nearest(key, 30, eps=0.5)
        assert len(np.unique(rows)) == 30 and dist.max() <= 1.5 * d_ref[-1] + 1e-12


def test_exact_rows_by_margin_are_the_general_rankings_order():
    """Exact rows by goal error, one per posture, then by joint-limit margin: as NumPy ranks.

    The reference is the general stages' own functions: :func:`best_distinct` over the exact
    rows, then :class:`JointLimitMargin` sorted stably. Ties in the goal error and in the
    cost (rows repeated) keep the row order.
    """
    from sik_ros.kernels.sets import exact_by_margin
    from sik_ros.solver.config import ORIENTATION_WEIGHT
    from sik_ros.solver.config import SolverConfig
    from sik_ros.solver.objectives import JointLimitMargin
    from sik_ros.solver.scores import assess, best_distinct
    robot = SelectiveIK.load('panda').robot
    cfg = SolverConfig()
    rng = np.random.default_rng(11)
    for trial in range(50):
        m = int(rng.integers(0, 30))
        q = rng.uniform(robot.lower, robot.upper, (m, robot.dof))
        perr = rng.choice([1e-6, 5e-5, 2e-4, 0.01], m)
        oerr = rng.choice([1e-5, 5e-4, 2e-3], m)
        if m > 4:  # repeated rows: equal scores and costs, one posture
            q[3], perr[3], oerr[3] = q[1], perr[1], oerr[1]
            q[4] = q[2] + 0.1
        keep, cost = exact_by_margin(q, perr, oerr, cfg.position_tolerance,
                                     cfg.orientation_tolerance, ORIENTATION_WEIGHT,
                                     cfg.distinct_threshold, robot.lower, robot.upper)
        c = assess(q, np.zeros((m, 1)), perr, oerr, 'pose', cfg)
        c = c.take(c.exact)
        ref = best_distinct(c, cfg.distinct_threshold, False)
        ref_cost = JointLimitMargin(robot)(ref.q)
        order = np.argsort(ref_cost, kind='stable')
        np.testing.assert_array_equal(q[keep], ref.q[order])
        np.testing.assert_array_equal(cost, ref_cost[order])


def test_the_cache_fallback_is_a_folder_private_to_the_user(tmp_path):
    """A new folder is made 0700; a folder others can write, or a link to one, is refused."""
    import os
    import stat
    from sik_ros.kernels._cache import private_folder
    fresh = tmp_path / 'fresh'
    assert private_folder(fresh)
    assert stat.S_IMODE(os.lstat(fresh).st_mode) == 0o700
    assert private_folder(fresh)  # again: it is ours and private
    shared = tmp_path / 'shared'
    shared.mkdir()
    os.chmod(shared, 0o777)
    assert not private_folder(shared)
    link = tmp_path / 'link'
    link.symlink_to(fresh)
    assert not private_folder(link)
    (tmp_path / 'file').write_text('')
    assert not private_folder(tmp_path / 'file')
