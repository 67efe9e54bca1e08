"""The peers the benchmarks time beside sik_ros, as users write them.

:class:`DLS`: single-solution damped least squares on Pinocchio (position goals). :class:`TracIK`:
TRAC-IK through pytracik (5 ms timeout, eps 1e-5, Speed), its joint limits set from the robot
(its URDF parse leaves some at zero). :class:`Frankik`: the Panda's analytic IK (``frankik``, He
and Liu's geometric solver), one solution for a value of joint 7.
"""

import numpy as np
import pinocchio as pin
import pytracik

from sik_ros.kinematics.robot import find_frame


class DLS:
    """Single-solution damped least squares on Pinocchio (position goals), as users write it."""

    def __init__(self, robot, tol=1e-4, iters=100, damping=1e-3, max_step=0.4):
        self.robot, self.tol, self.iters = robot, tol, iters
        self.damping, self.max_step = damping, max_step
        self.model, self.data = robot.model, robot.model.createData()
        self.fid = find_frame(robot.model, robot.tip_frame)
        self.base = find_frame(robot.model, robot.base_frame)

    def solve(self, target, q):
        """One solve from ``q``: (converged, q)."""
        for _ in range(self.iters):
            pin.framesForwardKinematics(self.model, self.data, q)
            tip = self.data.oMf[self.base].actInv(self.data.oMf[self.fid]).translation
            err = self.data.oMf[self.base].rotation @ (target - tip)
            if np.linalg.norm(target - tip) < self.tol:
                return True, q
            jac = pin.computeFrameJacobian(self.model, self.data, q, self.fid,
                                           pin.LOCAL_WORLD_ALIGNED)[:3]
            dq = jac.T @ np.linalg.solve(jac @ jac.T + self.damping ** 2 * np.eye(3), err)
            dq *= min(1.0, self.max_step / max(np.abs(dq).max(), 1e-12))
            q = np.clip(q + dq, self.robot.lower, self.robot.upper)
        return False, q


class TracIK:
    """TRAC-IK through pytracik (5 ms timeout, eps 1e-5, Speed), limits set from the robot."""

    def __init__(self, robot, timeout=0.005):
        self.robot = robot
        self.solver = pytracik.TRAC_IK(robot.base_frame, robot.tip_frame,
                                       robot.urdf_path.read_text(), timeout, 1e-5,
                                       pytracik.SolveType.Speed)
        pytracik.set_joint_limits(self.solver, list(robot.lower), list(robot.upper))

    def solve(self, position, quat, q0):
        """One solve from ``q0``: (converged, q)."""
        out = pytracik.ik(self.solver, q0, *position, *quat)
        q = np.asarray(out[1:], dtype=float)
        ok = out[0] >= 0 and len(q) == self.robot.dof and np.all(
            q >= self.robot.lower - 1e-9) and np.all(q <= self.robot.upper + 1e-9)
        return bool(ok), q


class Frankik:
    """The Panda's analytic IK (``frankik.ik``), as a user calls it for one solution.

    Joint 7 is the seed's first; when the pose has no solution within the limits there, the
    other values of a sweep of joint 7 are tried, nearest first. A solution counts when it is
    within the limits and its FK (Pinocchio's, our tip frame) meets the tolerances.
    """

    def __init__(self, robot, sweep: int = 64, tol=(1e-4, 1e-3)):
        import frankik
        self.robot, self.tol, self.ik = robot, tol, frankik.ik
        self.q7 = np.linspace(robot.lower[6], robot.upper[6], sweep)
        q = np.array([0.1, -0.4, 0.2, -2.0, 0.3, 1.5, 0.6])
        p, r = robot.fk_rot(q[None])
        ours = np.eye(4)
        ours[:3, :3], ours[:3, 3] = r[0], p[0]
        # frankik's pose is its flange's; ours is the tip frame: a fixed offset between them
        self.to_flange = np.linalg.inv(ours) @ frankik.fk(q) @ np.linalg.inv(
            frankik.FrankaKinematics.FrankaHandTCPOffset)

    def solve(self, position, quat, q0):
        """One solution near ``q0``: (converged, q)."""
        goal = np.eye(4)
        goal[:3, :3] = pin.Quaternion(quat[3], *quat[:3]).normalized().matrix()
        goal[:3, 3] = position
        goal = goal @ self.to_flange
        q = np.asarray(q0, dtype=float)
        for q7 in (q0[6], *sorted(self.q7, key=lambda v: abs(v - q0[6]))):
            q = np.asarray(self.ik(goal, np.asarray(q0, dtype=float), float(q7)), dtype=float)
            if np.isfinite(q).all() and np.all(q >= self.robot.lower - 1e-9) \
                    and np.all(q <= self.robot.upper + 1e-9):
                p, r = self.robot.fk_rot(q[None])
                perr = np.linalg.norm(p[0] - position)
                oerr = np.linalg.norm(pin.log3(r[0].T @ goal[:3, :3] @ np.linalg.inv(
                    self.to_flange)[:3, :3]))
                if perr < self.tol[0] and oerr < self.tol[1]:
                    return True, q
        return False, q
