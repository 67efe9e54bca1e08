"""What a training run reads: a dataset as tensors and its normaliser.

:class:`TrainData` holds a dataset's rows (or rows generated on the training device,
:mod:`~sik_ros.learning.generated_data`) as float32 tensors; :func:`default_normalizer`
centres and scales the workspace; :func:`turned_rot6` turns goal orientations for the cycle
term (warm starts: :mod:`~sik_ros.learning.warm_start`).
"""

from typing import Dict, TYPE_CHECKING, Union

import numpy as np
from scipy.spatial.transform import Rotation
import torch

from sik_ros.learning.generated_data import GeneratedData
from sik_ros.learning.models import make_goal, Normalizer
from sik_ros.tables.dataset import Dataset, dataset_summary

if TYPE_CHECKING:  # Pinocchio: a chain file's arm trains without it
    from sik_ros.kinematics.robot import Robot


class TrainData:
    """A dataset as float32 tensors: joints, goals, tip positions and rotations."""

    def __init__(self, ds: Union[Dataset, GeneratedData], goal: str,
                 uni_position: bool = False):
        if isinstance(ds, GeneratedData):  # already tensors, on the training device
            rows = distinct_positions(ds.position) if uni_position else None
            pick = (lambda t: t) if rows is None else (lambda t: t[rows])
            self.q, self.position, self.rot6 = pick(ds.q), pick(ds.position), pick(ds.rot6)
            self.goal = self.position if goal == 'position' else torch.cat(
                [self.position, self.rot6], 1)
            return
        rows = np.arange(len(ds))
        if uni_position:
            key = np.round(np.asarray(ds.position) * 1e5).astype(np.int64) + (1 << 20)
            keys = (key[:, 0] << 42) | (key[:, 1] << 21) | key[:, 2]
            _, rows = np.unique(keys, return_index=True)
        self.q = torch.from_numpy(np.asarray(ds.q)[rows].astype(np.float32))
        pos = np.asarray(ds.position)[rows]
        rot = Rotation.from_quat(np.asarray(ds.quaternion)[rows]).as_matrix()
        self.position = torch.from_numpy(pos.astype(np.float32))
        self.rot6 = torch.from_numpy(np.concatenate([rot[:, :, 0], rot[:, :, 1]], 1)
                                     .astype(np.float32))
        self.goal = torch.from_numpy(make_goal(goal, pos, rot).astype(np.float32))

    def to(self, device: torch.device) -> 'TrainData':
        """The rows moved to ``device`` (in place; nothing is copied where they are)."""
        for name in ('q', 'position', 'rot6', 'goal'):
            setattr(self, name, getattr(self, name).to(device))
        return self

    def __len__(self) -> int:
        """Number of rows."""
        return len(self.q)


def default_normalizer(robot: 'Robot', ds: Union[Dataset, GeneratedData]) -> Normalizer:
    """Joint limits and a workspace centre and scale taken from the data's tip positions."""
    if isinstance(ds, GeneratedData):
        sub = ds.workspace
    else:
        pos = np.asarray(ds.position)
        sub = pos[:: max(1, len(pos) // 200_000)]
    center = sub.mean(axis=0)
    scale = float(np.sqrt(((sub - center) ** 2).sum(axis=1).mean()))
    return Normalizer(tuple(robot.lower.tolist()), tuple(robot.upper.tolist()),
                      tuple(center.tolist()), scale)


def data_summary(ds: Union[Dataset, GeneratedData]) -> Dict:
    """What a checkpoint records of the data it was trained on."""
    return ds.summary() if isinstance(ds, GeneratedData) else dataset_summary(ds)


def distinct_positions(position: torch.Tensor) -> torch.Tensor:
    """The first row of each distinct tip position (rounded to 10 um), in the order of the keys.

    The rows ``np.unique(..., return_index=True)`` gives for a dataset (the paper's
    uni-position dataset), computed where the positions are.
    """
    key = torch.round(position.double() * 1e5).long() + (1 << 20)
    keys = (key[:, 0] << 42) | (key[:, 1] << 21) | key[:, 2]
    uniq, inverse = torch.unique(keys, return_inverse=True)
    rows = torch.arange(len(keys), device=keys.device)
    first = torch.full((len(uniq),), len(keys), dtype=torch.long, device=keys.device)
    return first.scatter_reduce(0, inverse, rows, 'amin')


def turned_rot6(rot6: torch.Tensor, std: float, gen: torch.Generator) -> torch.Tensor:
    """Rotations (two columns, (N, 6)) turned about random axes by angles of ``std`` [rad]."""
    n = len(rot6)
    a, b = rot6[:, :3], rot6[:, 3:]
    c = torch.linalg.cross(a, b)
    r = torch.stack([a, b, c], dim=2)
    w = torch.randn(n, 3, generator=gen, device=gen.device).to(rot6.device) * std
    theta = torch.linalg.norm(w, dim=1, keepdim=True).clamp_min(1e-12)
    k = w / theta
    kx = torch.zeros(n, 3, 3, device=rot6.device, dtype=rot6.dtype)
    kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    kx = kx - kx.transpose(1, 2)
    s, cth = torch.sin(theta)[:, :, None], torch.cos(theta)[:, :, None]
    turn = torch.eye(3, dtype=rot6.dtype, device=rot6.device) + s * kx + (1 - cth) * kx @ kx
    out = turn @ r
    return torch.cat([out[:, :, 0], out[:, :, 1]], 1)
