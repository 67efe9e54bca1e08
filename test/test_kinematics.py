"""Kinematics: batched FK and Jacobians against Pinocchio, robot loading errors."""

import numpy as np
import pinocchio as pin
import pytest

from sik_ros.errors import FrameNotFound, InvalidArgument, RobotNotFound
from sik_ros.robots import load_robot


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


def test_pinocchio_loop_matches_batched(panda):
    """The per-configuration Pinocchio path gives the batched FK and Jacobians."""
    q = np.random.default_rng(3).uniform(panda.lower, panda.upper, size=(25, panda.dof))
    p1, r1, j1 = panda.jacobian_batch(q)
    p2, r2, j2 = panda.jacobian_loop(q)
    p3, r3 = panda.fk_loop(q)
    np.testing.assert_allclose(p2, p1, atol=1e-12)
    np.testing.assert_allclose(r2, r1, atol=1e-12)
    np.testing.assert_allclose(j2, j1, atol=1e-12)
    np.testing.assert_allclose(p3, p1, atol=1e-12)
    np.testing.assert_allclose(r3, r1, atol=1e-12)


def test_rotation_log_matches_scipy_everywhere():
    """The SO(3) logarithm against SciPy's rotation vectors: random, near pi and near zero."""
    from scipy.spatial.transform import Rotation
    from sik_ros.rotations import rotation_log
    rots = Rotation.random(500, random_state=3)
    np.testing.assert_allclose(rotation_log(rots.as_matrix()), rots.as_rotvec(), atol=1e-9)
    edge = np.array([[np.pi, 0, 0], [0, np.pi - 1e-8, 0], [1e-12, 0, 0], [0.0, 0, 0]])
    out = rotation_log(Rotation.from_rotvec(edge).as_matrix())
    # at pi the axis' sign is either
    np.testing.assert_allclose(np.abs(out), np.abs(edge), atol=1e-7)
