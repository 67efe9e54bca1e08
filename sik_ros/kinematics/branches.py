"""Branch signs: which of a pose's isolated solutions a configuration of an arm is on.

An arm of six joints or fewer reaches a pose at isolated configurations, its *branches*
(shoulder, elbow and wrist up or down: eight for a UR5). Two branches are parted by the
configurations where the Jacobian loses rank, and those come in two kinds:

- a joint whose angle alone makes the Jacobian singular, whatever the others (a UR5's elbow
  stretched, ``q3 = 0``, and its wrist aligned, ``q5 = 0``): its *side*, the sign of
  ``sin(q_j - c_j)``, is one branch sign;
- the rest (a UR5's wrist centre on the first joint's axis): the sign of the Jacobian's
  determinant (a 6 x 6 Jacobian), the product of every factor, is the last one.

:func:`branch_signs` finds an arm's sign joints numerically (no joint is assumed: the
Jacobian's smallest singular value at a grid of each joint's angles, the others drawn at
random), and :meth:`BranchSigns.codes` gives each configuration its branch code, the signs as
bits. On a UR5 the eight branches of a pose have eight codes (checked on random poses,
``test_branches.py``); an arm whose branches share a code (a general 6R arm has up to 16
solutions) still gets starts for every code.
"""

from dataclasses import dataclass
import functools
from typing import Tuple

import numpy as np

from sik_ros.kernels.angles import flip_rows
from sik_ros.kernels.chain import branch_codes
from sik_ros.kinematics.robot import Robot

#: Angles of each joint tried as a singular angle (a grid over one turn).
GRID = 72
#: Random configurations at which a singular angle must make the Jacobian singular.
SAMPLES = 8
#: Smallest over largest singular value under which a Jacobian counts as singular.
SINGULAR = 1e-6
#: The ratio under which a grid angle is refined as a singular angle (it grows with the
#: distance from one: under it within a grid step of the Panda's elbow), and how much finer
#: the grid about it is (the Panda's elbow has two 0.044 rad apart).
NEAR_SINGULAR = 0.02
FINE = 8


@dataclass(frozen=True)
class BranchSigns:
    """An arm's branch signs: its sign joints, and whether the determinant's sign counts.

    Attributes:
        joints: the joints whose angle alone makes the Jacobian singular.
        centres: each one's singular angle [rad] (the other is half a turn on).
        determinant: whether the sign of the (square) Jacobian's determinant is a sign.
    """

    joints: Tuple[int, ...]
    centres: Tuple[float, ...]
    determinant: bool

    @property
    def count(self) -> int:
        """How many codes there are: two per sign."""
        return 2 ** (len(self.joints) + int(self.determinant))

    @functools.cached_property
    def joint_array(self) -> np.ndarray:
        """``joints`` as an int64 array (K,)."""
        return np.array(self.joints, dtype=np.int64)

    @functools.cached_property
    def centre_array(self) -> np.ndarray:
        """``centres`` as a float64 array (K,) [rad]."""
        return np.array(self.centres, dtype=float)

    def codes(self, robot: Robot, q: np.ndarray) -> np.ndarray:
        """(M,) int64: the branch code of each configuration ``q`` (M, n) [rad].

        Bit k (k < len(joints)): the k-th sign joint on the side ``sin(q_j - c_j) > 0``; the
        next bit: a positive determinant of the Jacobian (compiled:
        :func:`~sik_ros.kernels.chain.branch_codes`).
        """
        q = np.ascontiguousarray(np.atleast_2d(np.asarray(q, dtype=float)))
        return branch_codes(robot.frames, q, self.joint_array, self.centre_array,
                            self.determinant)


def branch_signs(robot: Robot, seed: int = 0) -> BranchSigns:
    """The branch signs of ``robot`` (an arm of six joints or fewer), found numerically.

    A joint is a sign joint when, at some angle of a grid of :data:`GRID` over a turn, the
    Jacobian is singular (:data:`SINGULAR`) at each of :data:`SAMPLES` random configurations
    with that angle; the smallest such angle in ``[0, pi)`` is its centre. The determinant
    counts for a 6 x 6 Jacobian.
    """
    q = np.random.default_rng(seed).uniform(robot.lower, robot.upper, (SAMPLES, robot.dof))
    columns = np.arange(robot.dof)
    joints, centres = [], []
    for j in range(robot.dof):
        for c in np.linspace(0.0, np.pi, GRID // 2, endpoint=False):
            if worst_ratio(robot, q, columns, j, c) <= SINGULAR:
                joints.append(j)
                centres.append(float(c))
                break
    return BranchSigns(tuple(joints), tuple(centres), robot.dof == 6)


def worst_ratio(robot: Robot, q: np.ndarray, columns: np.ndarray, j: int, c: float) -> float:
    """The Jacobian's columns ``columns`` nearest singular, with joint ``j`` at ``c`` [rad].

    The largest ratio of the smallest to the largest singular value over the configurations
    ``q`` (M, n), each with joint ``j`` set to ``c``.
    """
    qc = q.copy()
    qc[:, j] = c
    s = np.linalg.svd(robot.jacobian_batch(qc)[2][:, :, columns], compute_uv=False)
    return float(np.max(s[:, -1] / s[:, 0]))


def singular_angles(robot: Robot, held: int, seed: int = 0) -> Tuple[Tuple[int, float], ...]:
    """The angles at which one joint alone makes the arm, joint ``held`` fixed, singular.

    Joint ``held`` fixed, a 7-joint arm is a 6-joint one, whose branches at a pose these
    angles part (:func:`branch_signs`): the Panda's elbow stretched (joint 4 at about -0.47
    rad, off any grid) is one. Over a grid of :data:`GRID` angles of each other joint across
    a turn, the others drawn at random (:data:`SAMPLES`): where the Jacobian less column
    ``held`` comes near singular (:func:`worst_ratio` a local least under
    :data:`NEAR_SINGULAR`), a grid :data:`FINE` times finer across the two steps about it
    parts angles close together, and each of its local leasts is refined (bounded scalar
    minimisation) and kept where the ratio falls under :data:`SINGULAR`.

    Returns:
        (joint, angle [rad] in ``[-pi, pi)``) pairs, by joint and angle; a joint may have
        several (two singular angles need not lie half a turn apart).
    """
    from scipy.optimize import minimize_scalar
    q = np.random.default_rng(seed).uniform(robot.lower, robot.upper, (SAMPLES, robot.dof))
    columns = np.flatnonzero(np.arange(robot.dof) != held)

    def leasts(angles: np.ndarray, ratios: np.ndarray, closed: bool) -> np.ndarray:
        before = np.roll(ratios, 1) if closed else np.r_[np.inf, ratios[:-1]]
        after = np.roll(ratios, -1) if closed else np.r_[ratios[1:], np.inf]
        return angles[(ratios < NEAR_SINGULAR) & (ratios <= before) & (ratios <= after)]
    step = 2 * np.pi / GRID
    coarse = -np.pi + np.arange(GRID) * step
    found = set()
    for j in columns:
        ratio = functools.partial(worst_ratio, robot, q, columns, j)
        for c in leasts(coarse, np.array([ratio(c) for c in coarse]), True):
            fine = np.linspace(c - step, c + step, 2 * FINE + 1)
            for f in leasts(fine, np.array([ratio(x) for x in fine]), False):
                best = minimize_scalar(ratio, bounds=(f - step / FINE, f + step / FINE),
                                       method='bounded', options={'xatol': 1e-12})
                if best.fun <= SINGULAR:
                    found.add((int(j), float(np.mod(best.x + np.pi, 2 * np.pi) - np.pi)))
    unique = []
    for j, c in sorted(found):
        if not unique or unique[-1][0] != j or c - unique[-1][1] > 1e-6:
            unique.append((j, c))
    return tuple(unique)


def exact_flips(robot: Robot, seed: int = 0) -> Tuple[int, ...]:
    """The joints ``a`` whose half-turn flip ``(q_a + pi, -q_a+1, q_a+2 + pi)`` keeps the tip.

    Three consecutive joints whose axes meet in one point (a spherical shoulder or wrist,
    such as the Panda's first three) reach every tip pose a second way: the first and third
    turned by half a turn, the middle one mirrored. Checked at :data:`SAMPLES` random
    configurations (tip poses equal to 1e-9), no arm assumed.
    """
    rng = np.random.default_rng(seed)
    q = rng.uniform(robot.lower, robot.upper, (SAMPLES, robot.dof))
    p, r = robot.fk_rot(q)
    found = []
    for a in range(robot.dof - 2):
        flipped = flip(q, a)
        p2, r2 = robot.fk_rot(flipped)
        if np.allclose(p, p2, rtol=0, atol=1e-9) and np.allclose(r, r2, rtol=0, atol=1e-9):
            found.append(a)
    return tuple(found)


@functools.lru_cache(maxsize=16)
def robot_flips(robot: Robot) -> np.ndarray:
    """:func:`exact_flips` of ``robot`` as int64, found once per arm."""
    return np.array(exact_flips(robot), dtype=np.int64)


def flip(q: np.ndarray, a: int) -> np.ndarray:
    """Configurations (M, n) with joints ``a, a+1, a+2`` flipped (:func:`exact_flips`)."""
    out = np.array(q, dtype=float, order='C')
    flip_rows(out, a)
    return out
