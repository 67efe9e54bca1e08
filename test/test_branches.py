"""Branch signs: an arm's sign joints, each branch of a pose its own code, starts per code.

Also the stages that give every branch: rows polished onto their solutions, starts across a
sign joint, and every branch of a second arm's poses.
"""

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
    reals, ints = kernel_settings(cfg, 40, 0, False, False, True)
    refine_rows(robot.frames, robot.lower, robot.upper, as_arg(robot.periodic, bool), q,
                as_arg(p[0]), as_arg(r[0]), reals.copy(), ints, perr, oerr, status)
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


def on_solution(robot, q, p, r, steps=200):
    """``q`` taken onto the exact solution it stands for: Newton steps to machine precision.

    Each step at most 0.05 rad on a joint (a full step near a singularity can jump to another
    solution).
    """
    x = np.array(q, dtype=float)
    for _ in range(steps):
        tp, tr, jac = robot.jacobian_batch(x[None])
        dr = r @ tr[0].T
        angle = np.arccos(np.clip((np.trace(dr) - 1) / 2, -1, 1))
        axis = np.array([dr[2, 1] - dr[1, 2], dr[0, 2] - dr[2, 0], dr[1, 0] - dr[0, 1]])
        err = np.concatenate([p - tp[0], axis * (angle / (2 * np.sin(angle))
                                                 if angle > 1e-12 else 0.5)])
        if np.linalg.norm(err) < 1e-14:
            break
        step = np.linalg.lstsq(jac[0], err, rcond=None)[0]
        x = x + step / max(1.0, np.abs(step).max() / 0.05)
    return x


def stages(robot):
    """The solver's stages' context for ``robot`` alone (no models: refinement needs none)."""
    from sik_ros.solver.context import Context
    return Context(robot, {}, SolverConfig(), None, None)


def test_codes_are_the_jacobians_signs(ur5, signs):
    """The compiled codes are the sign joints' sides and NumPy's sign of the determinant."""
    q = np.random.default_rng(6).uniform(ur5.lower, ur5.upper, (500, ur5.dof))
    expected = np.zeros(len(q), dtype=np.int64)
    for bit, (j, c) in enumerate(zip(signs.joints, signs.centres)):
        expected |= (np.sin(q[:, j] - c) > 0).astype(np.int64) << bit
    expected |= (np.linalg.det(ur5.jacobian_batch(q)[2]) > 0).astype(np.int64) << 2
    assert len(set(expected.tolist())) == 8
    assert np.array_equal(signs.codes(ur5, q), expected)


def test_polished_rows_stand_on_their_solutions(ur5, signs):
    """Near a wrist singularity exact rows lie far from their solutions; polished, on them.

    Within the tolerances a row can stand a tenth of a radian from the solution it refines
    towards; polished, each stays exact and on its branch, within 2 mrad of its solution.
    """
    from sik_ros.solver.context import Goal
    from sik_ros.solver.families.branches import polished
    from sik_ros.solver.refine import errors, Refined
    q0 = np.array([0.7, 2.5, -1.7, 1.5, 3e-4, -2.7])  # the wrist nearly aligned
    p, r = ur5.fk_rot(q0[None])
    q = every_branch(ur5, q0)
    ctx = stages(ur5)
    goal = Goal(p[0], r[0])
    raw = Refined(q, *errors(ctx, q, goal))
    out = polished(ctx, goal, signs, raw)
    solutions = np.array([on_solution(ur5, x, p[0], r[0]) for x in q])

    def apart(a, b):  # [rad], angles wrapped (a polished periodic joint may turn)
        return np.linalg.norm(np.angle(np.exp(1j * (a - b))), axis=1)
    assert len(q) >= 50
    assert apart(q, solutions).max() > 0.1  # rows a branch's reach from their solutions
    assert np.all(out.perr <= 1e-4) and np.all(out.oerr <= 1e-3)
    assert np.array_equal(signs.codes(ur5, out.q), signs.codes(ur5, q))
    assert apart(out.q, solutions).max() < 2e-3


def test_every_branch_of_kinova_poses(tmp_path):
    """A second arm (a spherical wrist): the branch stages find every branch of its poses.

    From a small seed table, the table's starts, then :func:`other_branches` and
    :func:`polished`, as the solver takes them; the branches known: those and 300 refinements
    from uniform random starts, each taken onto its solution (angles wrapped, 0.1 rad apart).
    """
    from sik_ros.deadline import NO_DEADLINE
    from sik_ros.kinematics.robots import load_robot
    from sik_ros.kinematics.rotations import quaternion_matrix
    from sik_ros.solver.context import Goal
    from sik_ros.solver.families.branches import other_branches, polished
    from sik_ros.solver.scores import converged
    from sik_ros.solver.refine import refine
    kinova = load_robot('kinova')
    data = collect(kinova, tmp_path / 'kinova', sampler='uniform', samples=60000, seed=4)
    table = SeedTable.build(kinova, data, rows=60000, seed=1)
    ctx = stages(kinova)
    cfg = ctx.config
    # two poses near a singularity (pairs of branches a few hundredths of a radian apart,
    # rows within the tolerances a tenth from them), four drawn at random
    poses = [[0.201, 2.28, 0.724, -1.565, 3.798, -0.618],
             [3.933, 5.45, 0.516, 0.05, 4.626, -0.479]]
    poses += list(np.random.default_rng(3).uniform(kinova.lower, kinova.upper, (4, 6)))
    checked = 0
    for q0 in np.array(poses):
        pos, quat = kinova.fk(q0)
        p, r = kinova.fk_rot(q0[None])
        goal = Goal(np.asarray(pos, float), quaternion_matrix(quat))
        found = refine(ctx, table.starts(pos, quat, cfg.seed_starts), goal, NO_DEADLINE)
        found = polished(ctx, goal, table.signs,
                         other_branches(ctx, goal, table, found, NO_DEADLINE))
        ours = found.q[converged(found.perr, found.oerr, 'pose', cfg)]
        reference = [on_solution(kinova, x, p[0], r[0]) for x in every_branch(kinova, q0)]
        branch = branch_labels(np.ascontiguousarray(np.concatenate([ours, reference])), 0.1,
                               np.ones(kinova.dof, dtype=bool))
        known = set(branch.tolist())
        assert set(branch[:len(ours)].tolist()) == known
        checked += len(known)
    assert checked >= 6 * 2


def test_a_branch_across_a_sign_joint_starts_from_its_neighbour(ur5, signs):
    """A UR5 elbow nearly stretched: mirrored, a solution refines onto the branch beside it.

    The start: the elbow mirrored about its singular angle; refined, an exact solution of the
    code across the elbow (its bit and the determinant's), a branch apart from the first.
    """
    from sik_ros.deadline import NO_DEADLINE
    from sik_ros.kinematics.rotations import quaternion_matrix
    from sik_ros.solver.context import Goal
    from sik_ros.solver.families.branches import mirrored
    from sik_ros.solver.scores import converged
    from sik_ros.solver.refine import refine
    ctx = stages(ur5)
    checked = 0
    for q0 in ([1.1, 0.9, 0.085, 0.2, 2.4, 2.6], [-2.6, 1.6, -0.2, -1.0, 0.7, 0.3]):
        q0 = np.array(q0)
        pos, quat = ur5.fk(q0)
        starts = mirrored(ctx, signs, q0[None])
        assert len(starts) == 1 and starts[0, 2] == pytest.approx(-q0[2])
        r = refine(ctx, starts, Goal(np.asarray(pos, float), quaternion_matrix(quat)),
                   NO_DEADLINE)
        assert converged(r.perr, r.oerr, 'pose', ctx.config).all()
        assert signs.codes(ur5, r.q)[0] == signs.codes(ur5, q0[None])[0] ^ 0b101
        assert np.linalg.norm(r.q[0] - q0) > 0.1
        checked += 1
    assert checked == 2


def test_singular_angles_with_a_joint_held_find_the_pandas_elbow_off_the_grid():
    """Joint 7 held, the Panda's elbow stretched is a singular angle, though on no grid.

    The stretch, found apart from the Jacobian: the angle of joint 4 at which the distance
    between the shoulder (joint 2's origin, where axes 1-3 meet) and the wrist (joint 6's
    origin, where axes 5 and 6 meet) is largest, by Pinocchio's joint placements. Every angle
    found makes the Jacobian less column 7 singular at configurations other than those drawn
    to find it; none does without a joint held.
    """
    import pinocchio as pin
    from sik_ros.kinematics.branches import GRID, singular_angles, worst_ratio
    from sik_ros.kinematics.robots import load_robot
    panda = load_robot('panda')
    data = panda.model.createData()
    q4 = np.linspace(panda.lower[3], panda.upper[3], 20001)
    distance = []
    for x in q4:
        pin.forwardKinematics(panda.model, data, np.r_[0.3, 0.2, -0.4, x, 0.5, 1.0, 0.1])
        distance.append(np.linalg.norm(data.oMi[6].translation - data.oMi[2].translation))
    stretch = q4[int(np.argmax(distance))]
    angles = singular_angles(panda, 6)
    elbow = [c for j, c in angles if j == 3]
    assert any(abs(np.sin(c - stretch)) < 1e-3 for c in elbow)
    assert np.min(np.abs(np.mod(stretch, 2 * np.pi / GRID) - np.array([0, 2 * np.pi / GRID]))) \
        > 1e-3  # off the grid
    others = np.random.default_rng(9).uniform(panda.lower, panda.upper, (20, 7))
    for j, c in angles:
        assert worst_ratio(panda, others, np.arange(6), j, c) < 1e-5
        assert worst_ratio(panda, others, np.arange(7), j, c) > 1e-3
