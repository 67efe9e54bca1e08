"""Building a posture-index table from a trained model and its dataset.

Every dataset row is encoded to its posture index (:func:`encode_dataset`), the indices are grouped
into cells (:meth:`IndexTable.build`), and a position-goal table may keep each index decoded at
its cell's centre (:func:`decode_postures`) and keep only the indices the decoder realises there
(:func:`tip_errors`, :func:`mark_realised`). :func:`build_table` does all of it for a checkpoint.
"""

from typing import Callable, Dict, Optional

import numpy as np
import torch

from sik_ros.defaults import TableConfig
from sik_ros.errors import InvalidArgument
from sik_ros.kinematics.robot import Robot
from sik_ros.learning.checkpoints import model_from_checkpoint, model_signature
from sik_ros.learning.models import make_goal, ModelConfig, Normalizer
from sik_ros.tables.dataset import Dataset, dataset_summary
from sik_ros.tables.index_table import IndexTable

Progress = Optional[Callable[[int], None]]


@torch.no_grad()
def encode_dataset(model, cfg: ModelConfig, norm: Normalizer, ds: Dataset,
                   batch: int = 65536, progress: Progress = None):
    """Posture index of every dataset row, (N, latent) float32."""
    from scipy.spatial.transform import Rotation
    out = np.empty((len(ds), cfg.index_dim), dtype=np.float32)
    for s in range(0, len(ds), batch):
        pos = np.asarray(ds.position[s:s + batch])
        rot = Rotation.from_quat(np.asarray(ds.quaternion[s:s + batch])).as_matrix() \
            if cfg.goal == 'pose' else None
        goal = torch.from_numpy(make_goal(cfg.goal, pos, rot).astype(np.float32))
        q = torch.from_numpy(np.asarray(ds.q[s:s + batch], dtype=np.float32))
        z, _ = model.encode(norm.goal_to_net(goal), norm.q_to_net(q))
        out[s:s + batch] = z.numpy()
        if progress:
            progress(len(q))
    return out


#: Where a table row's decoded tip is checked (:func:`tip_errors`), in cell edges from its
#: cell's centre: the centre, and the neighbouring cells' centres along the axes (a goal takes
#: the indices of the cells around it, up to about a cell away).
PROBES = np.vstack([np.zeros(3), np.eye(3), -np.eye(3)])


@torch.no_grad()
def decode_at(model, norm: Normalizer, goals: np.ndarray, z: np.ndarray, lower: np.ndarray,
              upper: np.ndarray, batch: int = 65536) -> np.ndarray:
    """Indices (M, latent) decoded at position goals (M, 3) [m], (M, n) clipped [rad]."""
    out = np.empty((len(z), len(lower)), dtype=np.float32)
    for s in range(0, len(out), batch):
        goal = torch.from_numpy(make_goal('position', goals[s:s + batch], None)
                                .astype(np.float32))
        q = norm.q_from_net(model.decode(norm.goal_to_net(goal),
                                         torch.from_numpy(z[s:s + batch]))).double().numpy()
        out[s:s + batch] = np.clip(q, lower, upper)
    return out


def decode_postures(model, cfg: ModelConfig, norm: Normalizer, table: 'IndexTable',
                    lower: np.ndarray, upper: np.ndarray, batch: int = 65536) -> np.ndarray:
    """Every index of a position-goal table decoded at its cell's centre, (M, n) clipped [rad].

    Raises:
        InvalidArgument: a pose-goal model (its goals have an orientation a cell lacks).
    """
    if cfg.goal != 'position':
        raise InvalidArgument(f'decoded postures need a position-goal model; got {cfg.goal!r}')
    centers = table.cell_centers(np.arange(len(table.indices)))
    return decode_at(model, norm, centers, table.indices, lower, upper, batch)


def tip_errors(model, norm: Normalizer, table: IndexTable, robot: Robot,
               postures: np.ndarray) -> np.ndarray:
    """Worst distance [m] between a probe goal and the tip of each row decoded there, (M,).

    The probes are :data:`PROBES` (the cell's centre and one cell away along each axis);
    ``postures`` (M, n) [rad] are the rows decoded at their cells' centres already.
    """
    centers = table.cell_centers(np.arange(len(table.indices)))
    worst = np.zeros(len(centers))
    for probe in PROBES * table.cell:
        goals = centers + probe
        q = postures if not probe.any() else decode_at(model, norm, goals, table.indices,
                                                       robot.lower, robot.upper)
        tip, _ = robot.fk_batch(np.asarray(q, dtype=np.float64))
        np.maximum(worst, np.linalg.norm(tip - goals, axis=1), out=worst)
    return worst


def mark_realised(table: IndexTable, errors: np.ndarray, max_error: float) -> IndexTable:
    """The table with the rows whose ``errors`` [m] are within ``max_error`` [m] marked realised.

    Each cell has at least its row of least error marked. The look-up by position gives only
    the marked rows; every row stays for the look-up by orientation. The manifest's
    ``realised`` entry records the threshold, the probe distance [m] and the rows marked.
    """
    cell = np.repeat(np.arange(len(table.centers)), np.diff(table.offsets))
    best = np.minimum.reduceat(errors, table.offsets[:-1])
    mask = (errors <= max_error) | (errors == best[cell])
    manifest = dict(table.manifest, realised={'max_tip_error': float(max_error),
                                              'probe': table.cell,
                                              'entries': int(np.count_nonzero(mask))})
    return IndexTable(table.centers, table.offsets, table.indices, manifest, table.orientations,
                      table.postures, mask)


def build_table(ckpt: Dict, robot: Robot, ds: Dataset, cfg: TableConfig = TableConfig(),
                orientations: bool = True, postures: Optional[bool] = None,
                progress: Progress = None) -> IndexTable:
    """The index table of a checkpoint's model over a dataset.

    Args:
        ckpt: a SIK or PSIK checkpoint (or exported model) dict.
        robot: the robot of the checkpoint and the dataset.
        ds: the dataset to encode.
        cfg: cell size, per-cell limits and the largest decoded tip error kept.
        orientations: keep each index's tip orientation.
        postures: keep each index decoded at its cell's centre; None: for position models.
        progress: called with the number of rows encoded so far, chunk by chunk.

    Raises:
        InvalidArgument: not a SIK/PSIK model, or postures or a tip error asked for a pose
            model, or a tip error without postures.
    """
    model, mcfg, norm = model_from_checkpoint(ckpt)
    if mcfg.kind not in ('sik', 'psik'):
        raise InvalidArgument(f'a {mcfg.kind} model has no posture index; tables need sik/psik')
    postures = mcfg.goal == 'position' if postures is None else postures
    if postures and mcfg.goal != 'position':
        raise InvalidArgument('--postures needs a position-goal model (a pose goal has an '
                              'orientation that a cell centre lacks)')
    if cfg.max_tip_error > 0 and not postures:
        raise InvalidArgument('--max-tip-error needs --postures (a position-goal model): the '
                              'indices are checked decoded at their cells')
    z = encode_dataset(model, mcfg, norm, ds, progress=progress)
    manifest = {'robot': robot.manifest(), 'model': model_signature(ckpt),
                'dataset': dataset_summary(ds), 'goal': mcfg.goal}
    table = IndexTable.build(z, ds.position, cfg, manifest,
                             ds.quaternion if orientations else None)
    if postures:
        table = table.with_postures(
            decode_postures(model, mcfg, norm, table, robot.lower, robot.upper),
            robot.lower, robot.upper)
    if cfg.max_tip_error > 0:
        errors = tip_errors(model, norm, table, robot, table.postures)
        table = mark_realised(table, errors, cfg.max_tip_error)
    return table
