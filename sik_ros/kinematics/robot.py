"""Robot models on Pinocchio: arm reduction, batched forward kinematics and Jacobians.

A :class:`Robot` is a serial chain of revolute joints from a fixed base frame to a tip frame,
extracted from a Pinocchio model (example-robot-data or a URDF). Joints off the base-to-tip path
(a gripper's fingers) are locked. Its constant geometry is a
:class:`~sik_ros.kinematics.chain.SerialChain`;
tip poses and Jacobians come from the compiled kernels on it (:mod:`sik_ros.kernels.chain`),
tested against Pinocchio's own frame placements and Jacobians.
"""

from pathlib import Path
from typing import Optional, Sequence, Tuple

import numpy as np
import pinocchio as pin

from sik_ros.artifacts import file_sha256
from sik_ros.errors import InvalidArgument, InvalidModel
from sik_ros.kernels import as_arg, chain_frames, fk_many, jac_many
from sik_ros.kinematics.chain import SerialChain
from sik_ros.kinematics.model_tree import (chain_path, find_frame, pinocchio_reason, rename_frame,
                                           rename_link_joints, REVOLUTE_AXES)
from sik_ros.kinematics.periodic import periodic_joints
from sik_ros.kinematics.rotations import rotation_to_quaternion, z_to_axis


def sha256_file(path: Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    return file_sha256(path)


class Robot:
    """A robot arm as a revolute serial chain from ``base_frame`` to ``tip_frame``.

    Attributes:
        name: robot name (example-robot-data name, or the URDF's robot name).
        urdf_path: the URDF file the model was built from.
        urdf_sha256: SHA-256 of that file.
        model: the reduced Pinocchio model (arm joints only).
        joint_names: names of the arm joints, in chain order.
        lower, upper: joint limits (n,) [rad].
        chain: the chain geometry used by the batched kinematics.
    """

    def __init__(self, name: str, urdf_path: Path, full_model: pin.Model, base_frame: str,
                 tip_frame: str, package_dirs: Sequence[str] = (),
                 collision_urdf: Optional[Path] = None, srdf_path: Optional[Path] = None,
                 urdf_source: Optional[Path] = None):
        self.name = name
        self.urdf_path = Path(urdf_path)
        self.urdf_sha256 = sha256_file(self.urdf_path)
        self.urdf_source = None if urdf_source is None else Path(urdf_source)
        self.base_frame = base_frame
        self.tip_frame = tip_frame
        self._package_dirs = list(package_dirs)
        self._collision_urdf = Path(collision_urdf) if collision_urdf else self.urdf_path
        self._srdf_path = srdf_path
        path = chain_path(full_model, base_frame, tip_frame)
        # everything else is locked: joints off the chain (grippers, other limbs), those above
        # the base, and a floating or planar root
        lock = [j for j in range(1, full_model.njoints) if j not in path]
        q_ref = pin.neutral(full_model)
        kept_names = rename_link_joints(full_model, lock)
        self._locked = lock
        self._q_ref_full = q_ref
        try:
            self.model = pin.buildReducedModel(full_model, lock, q_ref) if lock else full_model
        except (RuntimeError, ValueError) as exc:
            raise InvalidModel(f'{name}: Pinocchio cannot reduce the model to the chain '
                               f'{base_frame!r} -> {tip_frame!r}: {pinocchio_reason(exc)}'
                               ) from exc
        for j in range(1, self.model.njoints):
            self.model.names[j] = kept_names.get(self.model.names[j], self.model.names[j])
        for i, frame in enumerate(self.model.frames):
            if frame.type == pin.FrameType.JOINT and frame.name in kept_names:
                rename_frame(self.model, i, kept_names[frame.name])
        self._full_model = full_model
        self.joint_names = [self.model.names[j] for j in range(1, self.model.njoints)]
        self.lower = np.array(self.model.lowerPositionLimit, dtype=float)
        self.upper = np.array(self.model.upperPositionLimit, dtype=float)
        if not (np.all(np.isfinite(self.lower)) and np.all(np.isfinite(self.upper))
                and np.all(self.upper > self.lower)):
            bad = [n for n, lo, hi in zip(self.joint_names, self.lower, self.upper)
                   if not (np.isfinite(lo) and np.isfinite(hi) and hi > lo)]
            raise InvalidModel(f'{name}: joints {bad} need finite limits with lower < upper')
        velocity = np.array(self.model.velocityLimit, dtype=float)
        #: joint velocity limits [rad/s] from the URDF (1 where it gives none)
        self.velocity_limits = np.where(np.isfinite(velocity) & (velocity > 0), velocity, 1.0)
        #: joints whose range spans a whole turn: q and q +- 2 pi are the same posture
        self.periodic = periodic_joints(self.lower, self.upper)
        self.chain = self._extract_chain()
        #: the chain as the kernels take it (:func:`~sik_ros.kernels.chain.chain_frames`)
        self.frames = chain_frames(self.chain)
        self.data = self.model.createData()
        self._tip_id = find_frame(self.model, tip_frame)
        self._base_id = find_frame(self.model, base_frame)
        self._collision = None

    # -- construction --------------------------------------------------------------------------

    def _extract_chain(self) -> SerialChain:
        m = self.model
        rots, trans, axes = [], [], []
        for j in range(1, m.njoints):
            if m.parents[j] != j - 1:
                raise InvalidModel(f'{self.name}: the reduced model is not a serial chain')
            joint = m.joints[j]
            kind = joint.shortname()
            if kind in REVOLUTE_AXES:
                axis = np.array(REVOLUTE_AXES[kind])
            elif kind == 'JointModelRevoluteUnaligned':
                axis = np.array(joint.extract().axis, dtype=float)
            else:
                raise InvalidModel(
                    f'{self.name}: joint {m.names[j]!r} is {kind}; only revolute joints are '
                    f'supported in the chain')
            placement = m.jointPlacements[j]
            rots.append(placement.rotation.copy())
            trans.append(placement.translation.copy())
            axes.append(axis / np.linalg.norm(axis))
        # turn every joint about its own z axis: R_i <- A_{i-1}^T R_i A_i, t_i <- A_{i-1}^T t_i
        align = [z_to_axis(a) for a in axes]
        prev = np.eye(3)
        for i, al in enumerate(align):
            rots[i] = prev.T @ rots[i] @ al
            trans[i] = prev.T @ trans[i]
            prev = al
        base = m.frames[find_frame(m, self.base_frame)]
        if base.parentJoint != 0:
            raise InvalidModel(f'base frame {self.base_frame!r} must be fixed to the world')
        base_inv = base.placement.inverse()
        tip = m.frames[find_frame(m, self.tip_frame)]
        if tip.parentJoint != m.njoints - 1:
            raise InvalidModel(f'tip frame {self.tip_frame!r} is not on the last arm joint')
        return SerialChain(
            joint_rotations=np.array(rots), joint_translations=np.array(trans),
            axes=np.array(axes), base_rotation=base_inv.rotation.copy(),
            base_translation=base_inv.translation.copy(),
            tip_rotation=prev.T @ tip.placement.rotation,
            tip_translation=prev.T @ tip.placement.translation)

    # -- kinematics ----------------------------------------------------------------------------

    @property
    def full_model(self) -> pin.Model:
        """The whole description's Pinocchio model (every joint, locked ones too; read only)."""
        return self._full_model

    @property
    def dof(self) -> int:
        """Number of arm joints."""
        return len(self.joint_names)

    def fk_batch(self, q: np.ndarray, chunk: int = 1 << 16) -> Tuple[np.ndarray, np.ndarray]:
        """Tip poses of many configurations.

        Args:
            q: (N, n) joint positions [rad].
            chunk: configurations computed at a time (bounds the temporary memory).

        Returns:
            positions (N, 3) [m] and quaternions (N, 4) x y z w, in the base frame.
        """
        q = self._check_q(q)
        pos = np.empty((len(q), 3))
        quat = np.empty((len(q), 4))
        for start in range(0, len(q), chunk):
            p, r = self.fk_rot(q[start:start + chunk])
            pos[start:start + chunk] = p
            quat[start:start + chunk] = rotation_to_quaternion(r)
        return pos, quat

    def fk_rot(self, q: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """Tip positions (N, 3) [m] and rotation matrices (N, 3, 3) of configurations (N, n)."""
        q = as_arg(self._check_q(q))
        pos, rot = np.empty((len(q), 3)), np.empty((len(q), 3, 3))
        fk_many(self.frames, q, pos, rot)
        return pos, rot

    def fk(self, q: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """Tip position (3,) [m] and quaternion (4,) x y z w of one configuration (n,)."""
        pos, quat = self.fk_batch(np.asarray(q, dtype=float).reshape(1, -1))
        return pos[0], quat[0]

    def jacobian_batch(self, q: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Tip poses and geometric Jacobians of many configurations.

        The Jacobian maps joint velocities to the tip's linear velocity [m/s] and angular
        velocity [rad/s] in the base frame, both taken at the tip (Pinocchio's
        ``LOCAL_WORLD_ALIGNED``).

        Returns:
            positions (N, 3), rotations (N, 3, 3), Jacobians (N, 6, n).
        """
        q = as_arg(self._check_q(q))
        pos, rot = np.empty((len(q), 3)), np.empty((len(q), 3, 3))
        jac = np.empty((len(q), 6, self.dof))
        jac_many(self.frames, q, pos, rot, jac)
        return pos, rot, jac

    def jacobian_loop(self, q: np.ndarray, data: Optional[pin.Data] = None
                      ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Same as :meth:`jacobian_batch` (``data`` is not needed: kept for callers)."""
        return self.jacobian_batch(q)

    def tip_poses(self, q: np.ndarray, data: Optional[pin.Data] = None
                  ) -> Tuple[np.ndarray, np.ndarray]:
        """Tip positions (N, 3) [m] and rotations (N, 3, 3): :meth:`fk_rot`."""
        return self.fk_rot(q)

    def pin_placement(self, q: np.ndarray) -> pin.SE3:
        """Tip placement in the base frame computed by Pinocchio itself (reference)."""
        q = np.asarray(q, dtype=float)
        pin.framesForwardKinematics(self.model, self.data, q)
        base = self.data.oMf[self._base_id]
        tip = self.data.oMf[self._tip_id]
        return base.actInv(tip)

    def pin_jacobian(self, q: np.ndarray) -> np.ndarray:
        """Tip Jacobian (6, n) from Pinocchio, LOCAL_WORLD_ALIGNED, base frame = world."""
        q = np.asarray(q, dtype=float)
        return pin.computeFrameJacobian(self.model, self.data, q,
                                        self._tip_id, pin.LOCAL_WORLD_ALIGNED)

    def _check_q(self, q: np.ndarray) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        if q.ndim != 2 or q.shape[1] != self.dof:
            raise InvalidArgument(
                f'joint array must have shape (N, {self.dof}); got {q.shape}')
        return q

    # -- geometry ------------------------------------------------------------------------------

    @property
    def collision_model(self) -> pin.GeometryModel:
        """The arm's collision geometry (coal), reduced like the kinematic model; loaded lazily."""
        if self._collision is None:
            self._collision = self._reduced_geometry(self._collision_urdf,
                                                     pin.GeometryType.COLLISION)
        return self._collision

    def visual_model(self) -> pin.GeometryModel:
        """The arm's visual geometry: the URDF's ``<visual>`` meshes and shapes.

        Reduced like the kinematic model (locked joints at their reference); loaded at each
        call.

        Raises:
            InvalidModel: a mesh that cannot be found or read.
        """
        return self._reduced_geometry(self.urdf_path, pin.GeometryType.VISUAL)

    def _reduced_geometry(self, urdf: Path, kind: pin.GeometryType) -> pin.GeometryModel:
        """A geometry model of ``urdf`` on the reduced model."""
        what = 'collision' if kind == pin.GeometryType.COLLISION else 'visual'
        try:
            full_geom = pin.buildGeomFromUrdf(self._full_model, str(urdf), kind,
                                              package_dirs=self._package_dirs)
        except (RuntimeError, ValueError) as exc:
            raise InvalidModel(f'{self.name}: cannot load the {what} geometry of '
                               f'{urdf}: {pinocchio_reason(exc)} (put the '
                               f'folder holding its package on ROS_PACKAGE_PATH, or source '
                               f'its ROS workspace)') from exc
        if not self._locked:
            return full_geom
        _, geom = pin.buildReducedModel(self._full_model, full_geom, self._locked,
                                        self._q_ref_full)
        return geom

    @property
    def srdf_path(self) -> Optional[Path]:
        """SRDF with the robot's disabled collision pairs, when known."""
        return self._srdf_path

    def manifest(self) -> dict:
        """What identifies this robot in an artifact's manifest.

        ``urdf`` (the file's absolute path) is there for a robot loaded from a URDF file, not
        for one loaded by its example-robot-data name; ``periodic`` (the names of the joints
        whose range spans a turn) only when there are some.
        """
        out = {
            'robot': self.name,
            'urdf_sha256': self.urdf_sha256,
            'base_frame': self.base_frame,
            'tip_frame': self.tip_frame,
            'joint_names': list(self.joint_names),
            'lower': self.lower.tolist(),
            'upper': self.upper.tolist(),
        }
        if self.urdf_source is not None:
            out['urdf'] = str(self.urdf_source.resolve())
        if self.periodic.any():
            out['periodic'] = [n for n, p in zip(self.joint_names, self.periodic) if p]
        return out
