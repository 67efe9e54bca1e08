"""Branch signs: an arm's sign joints, each branch of a pose its own code, starts per code."""

import numpy as np
import pytest

from sik_ros.kernels import as_arg, refine_rows
from sik_ros.kernels.families import branch_labels
from sik_ros.kinematics.branches import branch_signs
from sik_ros.solver.config import SolverConfig
from sik_ros.solver.refine import kernel_settings
from sik_ros.tables.dataset import collect
from sik_ros.tables.seed_table import SeedTable


@pytest.fixture(scope='module')
def signs(ur5):
    """The UR5's branch signs."""
    return branch_signs(ur5)


def every_branch(robot, q0, starts=300, seed=0):
    """Exact solutions (M, n) of the pose of ``q0`` refined from uniform random starts."""
    cfg = SolverConfig()
    p, r = robot.fk_rot(q0[None])
    q = np.random.default_rng(seed).uniform(robot.lower, robot.upper, (starts, robot.dof))
    perr, oerr = np.empty(starts), np.empty(starts)
    status = np.empty(starts, dtype=np.int8)
    reals, ints, prune_at = kernel_settings(cfg, 40, 0, False, False)
    refine_rows(robot.frames, robot.lower, robot.upper, as_arg(robot.periodic, bool), q,
                as_arg(p[0]), as_arg(r[0]), True, reals.copy(), ints, prune_at, perr, oerr,
                status)
    return q[(perr <= cfg.position_tolerance) & (oerr <= cfg.orientation_tolerance)]


def test_sign_joints_make_the_jacobian_singular(ur5, signs):
    """At each sign joint's centre the Jacobian loses rank whatever the other joints."""
    # a UR5: elbow and wrist, and its shoulder by the determinant: 8 codes, its 8 branches
    assert len(signs.joints) == 2 and signs.determinant and signs.count == 8
    q = np.random.default_rng(3).uniform(ur5.lower, ur5.upper, (20, ur5.dof))
    for j, c in zip(signs.joints, signs.centres):
        for angle in (c, c + np.pi):
            qc = q.copy()
            qc[:, j] = angle
            s = np.linalg.svd(ur5.jacobian_batch(qc)[2], compute_uv=False)
            assert np.all(s[:, -1] < 1e-6 * s[:, 0])
    s = np.linalg.svd(ur5.jacobian_batch(q)[2], compute_uv=False)
    assert np.all(s[:, -1] > 1e-6 * s[:, 0])  # random configurations are not singular


def test_each_branch_of_a_pose_has_its_own_code(ur5, signs):
    """The branches of UR5 poses (angles wrapped) have one code each, no two alike."""
    rng = np.random.default_rng(5)
    checked = poses = 0
    for t in range(8):
        q = every_branch(ur5, rng.uniform(ur5.lower, ur5.upper), seed=t)
        sides = np.sin(q[:, list(signs.joints)] - np.array(signs.centres))
        if np.abs(sides).min() < 0.1:
            continue  # two branches within a branch's reach of a singularity: one label
        poses += 1
        branch = branch_labels(np.ascontiguousarray(q), 0.1, np.ones(ur5.dof, dtype=bool))
        codes = signs.codes(ur5, q)
        per_branch = {b: set(codes[branch == b].tolist()) for b in set(branch.tolist())}
        assert all(len(c) == 1 for c in per_branch.values())
        assert len({next(iter(c)) for c in per_branch.values()}) == len(per_branch)
        checked += len(per_branch)
    assert poses >= 5 and checked >= 4 * poses  # at least four branches a pose told apart


def test_branch_starts_come_from_one_code(ur5, tmp_path):
    """A seed table's starts for a code are its rows of that code, near the goal's tip pose."""
    data = collect(ur5, tmp_path / 'ur5', sampler='uniform', samples=8000, seed=4)
    table = SeedTable.build(ur5, data, rows=4000, seed=1)
    assert table.signs is not None and len(table.codes) == len(table)
    rng = np.random.default_rng(2)
    counted = 0
    for q0 in rng.uniform(ur5.lower, ur5.upper, (4, ur5.dof)):
        p, quat = ur5.fk(q0)
        for code in range(table.signs.count):
            starts = table.branch_starts(p, quat, code, 2)
            assert 1 <= len(starts) <= 2
            assert np.all(table.signs.codes(ur5, starts) == code)
            counted += len(starts)
    assert counted >= 4 * table.signs.count


def test_exact_flips_keep_the_tip_and_turn_into_the_limits():
    """A spherical wrist's flip (the Kinova's joints 4-6) reaches the same pose, by Pinocchio.

    Turned by whole turns into the limits (as the solver's starts are), it is a configuration
    within them at that pose; the UR5 (offset wrist) has no exact flip.
    """
    from sik_ros.kinematics.branches import exact_flips, flip
    from sik_ros.kernels.angles import TURN
    from sik_ros.kinematics.robots import load_robot
    kinova = load_robot('kinova')
    assert exact_flips(kinova) == (3,) and exact_flips(load_robot('ur5')) == ()
    q = np.random.default_rng(4).uniform(kinova.lower, kinova.upper, (20, kinova.dof))
    turned = kinova.lower + np.mod(flip(q, 3) - kinova.lower, TURN)
    fits = np.all(turned <= kinova.upper, axis=1)
    assert fits.sum() >= 10
    for a, b in zip(q[fits], turned[fits]):
        pa, pb = kinova.pin_placement(a), kinova.pin_placement(b)
        assert np.allclose(pa.translation, pb.translation, atol=1e-9)
        assert np.allclose(pa.rotation, pb.rotation, atol=1e-9)
