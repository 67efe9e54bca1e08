"""Kinematics: batched FK and Jacobians against Pinocchio, robot loading errors."""

import numpy as np
import pinocchio as pin
import pytest

from sik_ros.errors import FrameNotFound, InvalidArgument, RobotNotFound
from sik_ros.kinematics.robots import load_robot


def test_panda_is_reduced_to_seven_arm_joints(panda):
    """The Panda's fingers are locked: 7 arm joints with the URDF's limits."""
    assert panda.joint_names == [f'panda_joint{i}' for i in range(1, 8)]
    assert panda.lower[3] == pytest.approx(-3.0718)
    assert panda.upper[5] == pytest.approx(3.7525)


def test_batched_fk_matches_pinocchio(panda):
    """Batched FK equals Pinocchio's own frame placement to 1e-9 m on random configurations."""
    rng = np.random.default_rng(0)
    q = rng.uniform(panda.lower, panda.upper, size=(300, panda.dof))
    pos, quat = panda.fk_batch(q, chunk=64)
    for i in range(len(q)):
        ref = panda.pin_placement(q[i])
        np.testing.assert_allclose(pos[i], ref.translation, atol=1e-9)
        rot = pin.Quaternion(quat[i][[3, 0, 1, 2]][0], *quat[i][:3]).toRotationMatrix()
        np.testing.assert_allclose(rot, ref.rotation, atol=1e-9)


def test_single_fk_returns_unit_quaternion(panda):
    """fk() of one configuration gives a (3,) position and a unit (4,) quaternion."""
    p, q = panda.fk(np.zeros(panda.dof).clip(panda.lower, panda.upper))
    assert p.shape == (3,) and q.shape == (4,)
    assert np.linalg.norm(q) == pytest.approx(1.0)


def test_jacobian_matches_pinocchio(panda):
    """The batched geometric Jacobian equals Pinocchio's LOCAL_WORLD_ALIGNED frame Jacobian."""
    rng = np.random.default_rng(1)
    q = rng.uniform(panda.lower, panda.upper, size=(50, panda.dof))
    _, _, jac = panda.jacobian_batch(q)
    for i in range(len(q)):
        np.testing.assert_allclose(jac[i], panda.pin_jacobian(q[i]), atol=1e-9)


def test_wrong_shape_is_refused(panda):
    """A joint array of the wrong width raises InvalidArgument naming the expected shape."""
    with pytest.raises(InvalidArgument, match=r'\(N, 7\)'):
        panda.fk_batch(np.zeros((3, 6)))


def test_unknown_robot_lists_available():
    """An unknown robot name lists the robots that exist."""
    with pytest.raises(RobotNotFound, match='available: .*panda'):
        load_robot('no_such_robot')


def test_urdf_without_frame_lists_frames(panda):
    """A URDF whose tip frame does not exist lists the frames it has."""
    with pytest.raises(FrameNotFound, match='panda_hand_tcp'):
        load_robot('x', str(panda.urdf_path), 'panda_link0', 'no_such_frame')


def test_urdf_loading_matches_named_robot(panda):
    """Loading the Panda from its URDF path gives the same kinematics as by name."""
    from_urdf = load_robot('x', str(panda.urdf_path), 'panda_link0', 'panda_hand_tcp')
    assert from_urdf.joint_names == panda.joint_names
    q = np.random.default_rng(2).uniform(panda.lower, panda.upper, size=(20, 7))
    np.testing.assert_allclose(from_urdf.fk_batch(q)[0], panda.fk_batch(q)[0], atol=1e-12)


def test_collision_geometry_is_loaded(panda):
    """The arm's collision geometry is available (coal objects through Pinocchio)."""
    geom = panda.collision_model
    assert geom.ngeoms > 7


@pytest.mark.parametrize('name', ['panda', 'ur5', 'kinova', 'z1'])
def test_kernels_match_pinocchio_on_several_arms(name):
    """The compiled FK and Jacobian equal Pinocchio's to 1e-12 (periodic joints included).

    The Kinova's continuous joints are periodic revolute joints over +-2 pi; configurations
    are drawn over the whole ranges.
    """
    robot = load_robot(name)
    q = np.random.default_rng(4).uniform(robot.lower, robot.upper, size=(40, robot.dof))
    p, r, jac = robot.jacobian_batch(q)
    p2, r2 = robot.fk_rot(q)
    np.testing.assert_array_equal(p2, p)
    np.testing.assert_array_equal(r2, r)
    base_id = robot.model.getFrameId(robot.base_frame)
    for i in range(len(q)):
        ref = robot.pin_placement(q[i])
        np.testing.assert_allclose(p[i], ref.translation, rtol=0, atol=1e-12)
        np.testing.assert_allclose(r[i], ref.rotation, rtol=0, atol=1e-12)
        # Pinocchio's Jacobian is in the world frame: turned into the base frame
        turn = robot.data.oMf[base_id].rotation.T
        world = robot.pin_jacobian(q[i])
        ref_jac = np.concatenate([turn @ world[:3], turn @ world[3:]])
        np.testing.assert_allclose(jac[i], ref_jac, rtol=0, atol=1e-12)


def test_kernels_match_the_vectorised_chain(panda):
    """The kernels' FK equals the NumPy chain FK the training loss uses, to 1e-12."""
    from sik_ros.kinematics.chain import chain_forward
    q = np.random.default_rng(3).uniform(panda.lower, panda.upper, size=(25, panda.dof))
    p1, r1 = chain_forward(panda.chain, q)
    p2, r2 = panda.fk_rot(q)
    np.testing.assert_allclose(p2, p1, rtol=0, atol=1e-12)
    np.testing.assert_allclose(r2, r1, rtol=0, atol=1e-12)


def test_kernels_refuse_other_types(panda):
    """The kernels are compiled for their declared types only: others are refused, not compiled."""
    from sik_ros.kernels import fk_many
    q = np.zeros((2, panda.dof), dtype=np.float32)
    with pytest.raises(TypeError):
        fk_many(panda.frames, q, np.empty((2, 3)), np.empty((2, 3, 3)))


def test_rotation_error_kernel_matches_scipy_near_pi():
    """The kernels' rotation error equals SciPy's rotation vector, also at and near pi."""
    from scipy.spatial.transform import Rotation
    from sik_ros.kernels.chain import rotation_error
    vecs = np.concatenate([Rotation.random(200, random_state=5).as_rotvec(),
                           [[np.pi, 0, 0], [0, np.pi - 1e-8, 0], [0, 0, 1e-12],
                            [np.pi / np.sqrt(2), -np.pi / np.sqrt(2), 0.0]]])
    out = np.empty(3)
    for v in vecs:
        norm = rotation_error(Rotation.from_rotvec(v).as_matrix(), np.eye(3), out)
        assert norm == pytest.approx(np.linalg.norm(v), abs=1e-7)
        if np.linalg.norm(v) < np.pi - 1e-6:
            np.testing.assert_allclose(out, v, atol=1e-9)
        else:  # at pi the axis' sign is either
            np.testing.assert_allclose(np.abs(out), np.abs(v), atol=1e-7)


def test_rotation_log_matches_scipy_everywhere():
    """The SO(3) logarithm against SciPy's rotation vectors: random, near pi and near zero."""
    from scipy.spatial.transform import Rotation
    from sik_ros.kinematics.rotations import rotation_log
    rots = Rotation.random(500, random_state=3)
    np.testing.assert_allclose(rotation_log(rots.as_matrix()), rots.as_rotvec(), atol=1e-9)
    edge = np.array([[np.pi, 0, 0], [0, np.pi - 1e-8, 0], [1e-12, 0, 0], [0.0, 0, 0]])
    out = rotation_log(Rotation.from_rotvec(edge).as_matrix())
    # at pi the axis' sign is either
    np.testing.assert_allclose(np.abs(out), np.abs(edge), atol=1e-7)
