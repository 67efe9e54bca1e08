"""What a training run reads: a dataset as tensors, its normaliser, and warm starts.

:class:`TrainData` holds a dataset's rows as float32 tensors; :func:`default_normalizer`
centres and scales the workspace; :func:`turned_rot6` turns goal orientations for the cycle
term; :func:`widens` and :func:`widened_state` start a model with a wider posture index from a
smaller one (``sik-train --init``).
"""

from dataclasses import replace
from typing import Dict

import numpy as np
from scipy.spatial.transform import Rotation
import torch

from sik_ros.dataset import Dataset
from sik_ros.errors import ArtifactMismatch
from sik_ros.kinematics import Robot
from sik_ros.models import make_goal, ModelConfig, Normalizer


class TrainData:
    """A dataset as float32 tensors: joints, goals, tip positions and rotations."""

    def __init__(self, ds: Dataset, goal: str, uni_position: bool = False):
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

    def __len__(self) -> int:
        """Number of rows."""
        return len(self.q)


def default_normalizer(robot: Robot, ds: Dataset) -> Normalizer:
    """Joint limits and a workspace centre and scale taken from the dataset."""
    pos = np.asarray(ds.position)
    sub = pos[:: max(1, len(pos) // 200_000)]
    center = sub.mean(axis=0)
    scale = float(np.sqrt(((sub - center) ** 2).sum(axis=1).mean()))
    return Normalizer(tuple(robot.lower.tolist()), tuple(robot.upper.tolist()),
                      tuple(center.tolist()), scale)


def turned_rot6(rot6: torch.Tensor, std: float, gen: torch.Generator) -> torch.Tensor:
    """Rotations (two columns, (N, 6)) turned about random axes by angles of ``std`` [rad]."""
    n = len(rot6)
    a, b = rot6[:, :3], rot6[:, 3:]
    c = torch.linalg.cross(a, b)
    r = torch.stack([a, b, c], dim=2)
    w = torch.randn(n, 3, generator=gen).to(rot6.device) * std  # rotation vectors
    theta = torch.linalg.norm(w, dim=1, keepdim=True).clamp_min(1e-12)
    k = w / theta
    kx = torch.zeros(n, 3, 3, device=rot6.device, dtype=rot6.dtype)
    kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    kx = kx - kx.transpose(1, 2)
    s, cth = torch.sin(theta)[:, :, None], torch.cos(theta)[:, :, None]
    turn = torch.eye(3, dtype=rot6.dtype, device=rot6.device) + s * kx + (1 - cth) * kx @ kx
    out = turn @ r
    return torch.cat([out[:, :, 0], out[:, :, 1]], 1)


def widens(old: ModelConfig, new: ModelConfig) -> bool:
    """Whether ``new`` is ``old`` with a wider posture index (more learned elements or bits)."""
    same = replace(new, latent_dim=old.latent_dim, branches=old.branches) == old
    return (same and old.kind == 'sik' and new.latent_dim >= old.latent_dim
            and tuple(new.branches[:len(old.branches)]) == tuple(old.branches))


def widened_state(fresh: Dict, old: Dict, old_cfg: ModelConfig, cfg: ModelConfig) -> Dict:
    """``old`` weights in a model with a wider index (``fresh``: its initial state dict).

    The decoder's first layer keeps its goal and old index columns; the new learned elements'
    and bits' columns are zero. The encoder's last layer keeps its old outputs; new outputs
    take a tenth of their initial weights.
    """
    out = {k: v.clone() for k, v in fresh.items()}
    enc_last = 'encoder.%d.' % max(int(k.split('.')[1]) for k in old if k.startswith('encoder.'))
    for key, value in old.items():
        target = out[key]
        if target.shape == value.shape:
            out[key] = value.clone()
        elif key == 'decoder.0.weight':
            w = torch.zeros_like(target)
            g = cfg.goal_dim
            w[:, :g + old_cfg.latent_dim] = value[:, :g + old_cfg.latent_dim]
            bits = len(old_cfg.branches)
            if bits:  # the old bits keep theirs, after the wider learned part
                w[:, g + cfg.latent_dim:g + cfg.latent_dim + bits] = \
                    value[:, g + old_cfg.latent_dim:]
            out[key] = w
        elif key.startswith(enc_last):
            w = target * 0.1
            w[:value.shape[0]] = value
            out[key] = w
        else:
            raise ArtifactMismatch(f'weights {key} of the smaller model', tuple(target.shape),
                                   tuple(value.shape))
    return out
