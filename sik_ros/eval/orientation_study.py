"""Section 5 of the paper's experiments: orientation as a goal, raw and refined postures.

A few reachable pose targets; at each, postures of the index table's pool far apart,
decoded raw and refined, with their orientation errors (:func:`orientation_study`).
"""

from dataclasses import dataclass
from typing import List

import numpy as np
from scipy.spatial.transform import Rotation

from sik_ros.eval.metrics import orientation_cosine, pin_tips
from sik_ros.eval.studies import table_pool
from sik_ros.kinematics.goal_error import goal_errors
from sik_ros.solver import SelectiveIK
from sik_ros.solver.codec import decode
from sik_ros.solver.context import Goal
from sik_ros.solver.refine import refine
from sik_ros.tables.point_sets import farthest_point_subset


@dataclass
class OrientedTarget:
    """Experiment 5 at one pose target.

    Attributes:
        position: the target position (3,) [m]; ``quaternion`` its orientation (x y z w).
        z: the posture indices (postures, latent).
        q_raw, q_refined: the solutions (postures, n) [rad].
        err_raw, err_refined: their distance errors [m].
        cos_raw, cos_refined: their orientation cosine similarities (see
            :func:`sik_ros.eval.metrics.orientation_cosine`).
        angle_raw, angle_refined: their orientation errors [rad].
    """

    position: np.ndarray
    quaternion: np.ndarray
    z: np.ndarray
    q_raw: np.ndarray
    err_raw: np.ndarray
    cos_raw: np.ndarray
    angle_raw: np.ndarray
    q_refined: np.ndarray
    err_refined: np.ndarray
    cos_refined: np.ndarray
    angle_refined: np.ndarray


@dataclass
class Orientation:
    """Experiment 5: every target, and the means over every posture of every target.

    Attributes:
        targets: one :class:`OrientedTarget` each.
        err_raw, err_refined: mean distance errors [m].
        cos_raw, cos_refined: mean cosine similarities.
        angle_raw, angle_refined: mean orientation errors [rad].
    """

    targets: List[OrientedTarget]
    err_raw: float
    cos_raw: float
    angle_raw: float
    err_refined: float
    cos_refined: float
    angle_refined: float


#: Table rows nearest a pose goal's orientation that the orientation study's postures come
#: from, for a pose model whose index has several elements.
ORIENTED_POOL = 24


def orientation_study(ik: SelectiveIK, targets: int = 4, postures: int = 5,
                      seed: int = 5, min_height: float = 0.1) -> Orientation:
    """Experiment 5: pose goals (position and orientation held) with the pose model.

    Targets are reachable poses: FK of seeded uniform joint samples, the first ``targets`` whose
    tip is higher than ``min_height`` [m] above the base (above the table). Per target, the indices
    are the 0, 25, 50, 75 and 100 % quantiles (``postures`` of them) of the table's indices near
    the target's position (for a 1-d index, evenly spread along its range); for an index of
    several elements, ``postures`` far-apart ones among the :data:`ORIENTED_POOL` table rows
    nearest the target's orientation.
    """
    rng = np.random.default_rng(seed)
    q_goal = rng.uniform(ik.robot.lower, ik.robot.upper, (50 * targets, ik.robot.dof))
    pos_all, rot_all = ik.robot.fk_rot(q_goal)
    above = np.flatnonzero(pos_all[:, 2] > min_height)[:targets]
    pos_all, rot_all = pos_all[above], rot_all[above]
    out = []
    for pos, rot in zip(pos_all, rot_all):
        table = ik.models['pose'].table
        pool = table_pool(table, pos, ik.config.k_cells).astype(np.float64)
        quat = Rotation.from_matrix(rot).as_quat()
        if ik.models['pose'].cfg.latent_dim > 1 and table.orientations is not None:
            # an index of several elements stands for a posture of the whole position's
            # self-motion: the table rows nearest the goal's orientation (as the solver looks
            # them up), far apart
            rows = table.oriented_rows(pos, quat, ORIENTED_POOL, ik.config.oriented_cells)
            pool = table.indices[rows].astype(np.float64)
            z = pool[farthest_point_subset(pool, postures)]
        elif getattr(ik.models['pose'].cfg, 'branches', ()):
            # a branch code is a sign, not a quantity: the table's own indices at the
            # quantiles of the first learned element, each with its code
            order = np.argsort(pool[:, 0], kind='stable')
            z = pool[order[np.round(np.linspace(0, len(pool) - 1, postures)).astype(int)]]
        else:
            z = np.quantile(pool, np.linspace(0, 1, postures), axis=0)
        q_raw = decode(ik.context, Goal(pos, rot), z)
        q_ref = refine(ik.context, q_raw, Goal(pos, rot)).q
        rec = {}
        for tag, q in (('raw', q_raw), ('refined', q_ref)):
            p, r = pin_tips(ik.robot, q)
            cos, angle = orientation_cosine(rot, r)
            rec.update({f'q_{tag}': q, f'err_{tag}': goal_errors(p, r, pos)[0],
                        f'cos_{tag}': cos, f'angle_{tag}': angle})
        out.append(OrientedTarget(pos, Rotation.from_matrix(rot).as_quat(), z, **rec))
    means = {f'{key}_{tag}': float(np.mean([getattr(t, f'{key}_{tag}') for t in out]))
             for tag in ('raw', 'refined') for key in ('err', 'cos', 'angle')}
    return Orientation(out, **means)
