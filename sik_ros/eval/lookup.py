"""The paper's protocol: the look-up's indices decoded at the target, none selected by error.

The paper answers a target with the posture indices its KD-tree and dictionary give (those of the
collected poses nearest the target) and decodes each of them as it is. Here, for one target:

- a position model takes the indices of the table cells nearest the target, nearest cell
  first, as few cells as give at least :data:`MIN_INDICES` indices (every index those cells
  hold for the look-up by position: :meth:`~sik_ros.tables.index_table.IndexTable.rows_near`);
- a pose model takes the :data:`POSE_INDICES` rows of the cells around the target whose tips had
  the orientation nearest the target's (the paper's KD-tree over poses,
  :meth:`~sik_ros.tables.index_table.IndexTable.oriented_rows`);

every index is decoded at the target, and every one counts: the target's error is the mean over
all of them. Errors are measured with Pinocchio's forward kinematics (:func:`pin_tips`), not the
project's own kernels.
"""

from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np
from scipy.spatial.transform import Rotation

from sik_ros.eval.metrics import orientation_cosine, pin_tips
from sik_ros.solver import SelectiveIK
from sik_ros.solver.codec import decode
from sik_ros.solver.context import Goal

#: Fewest indices decoded per target.
MIN_INDICES = 10
#: Indices a pose model's look-up gives per target (the rows nearest the goal's orientation).
POSE_INDICES = 10


def lookup_rows(table, position: np.ndarray, minimum: int = MIN_INDICES) -> np.ndarray:
    """The table rows of the cells nearest ``position`` [m]: as few cells as give ``minimum``.

    The cells are taken nearest first, one more at a time, until their rows (those the
    look-up by position gives: the realised ones of a table that marks them) number at least
    ``minimum``, or the table has no more cells.
    """
    total = len(table) if hasattr(table, 'centers') else 1
    position = np.asarray(position, dtype=float)
    cells = 1
    while True:
        rows = table.rows_near(position, cells)
        if len(rows) >= minimum or cells >= total:
            return rows
        cells += 1


@dataclass
class LookupErrors:
    """Per target: the mean over every looked-up index decoded there, and how many there were.

    Attributes:
        distance: mean distance error [m], (targets,).
        count: indices decoded, (targets,).
        angle: mean orientation error [rad], (targets,) (pose goals; None for position goals).
    """

    distance: np.ndarray
    count: np.ndarray
    angle: Optional[np.ndarray] = None


#: Called with how many steps of work were just done.
Progress = Optional[Callable[[int], None]]


def position_lookup(ik: SelectiveIK, targets: np.ndarray,
                    progress: Progress = None) -> LookupErrors:
    """The protocol for a position model at targets (N, 3) [m]."""
    table = ik.models['position'].table
    targets = np.asarray(targets, dtype=float)
    dist, count = np.empty(len(targets)), np.empty(len(targets), dtype=int)
    for i, p in enumerate(targets):
        rows = lookup_rows(table, p)
        q = decode(ik.context, Goal(p), table.indices[rows])
        tip, _ = pin_tips(ik.robot, q)
        dist[i], count[i] = np.linalg.norm(tip - p, axis=1).mean(), len(rows)
        if progress:
            progress(1)
    return LookupErrors(dist, count)


def pose_lookup(ik: SelectiveIK, positions: np.ndarray, rotations: np.ndarray,
                count: int = POSE_INDICES) -> LookupErrors:
    """The protocol for a pose model at targets: positions (N, 3) [m], rotations (N, 3, 3)."""
    table = ik.models['pose'].table
    cells = max(ik.config.oriented_cells, count)
    n = len(positions)
    dist, angle, used = np.empty(n), np.empty(n), np.empty(n, dtype=int)
    for i, (p, rot) in enumerate(zip(np.asarray(positions, dtype=float), rotations)):
        quat = Rotation.from_matrix(rot).as_quat()
        rows = table.oriented_rows(p, quat, count, cells)
        q = decode(ik.context, Goal(p, rot), table.indices[rows])
        tip, r = pin_tips(ik.robot, q)
        dist[i] = np.linalg.norm(tip - p, axis=1).mean()
        angle[i] = orientation_cosine(rot, r)[1].mean()
        used[i] = len(rows)
    return LookupErrors(dist, used, angle)
