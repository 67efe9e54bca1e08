"""What a training run reads: a dataset as tensors, its normaliser, and warm starts.

:class:`TrainData` holds a dataset's rows (or rows generated on the training device,
:mod:`~sik_ros.learning.generated_data`) as float32 tensors; :func:`default_normalizer`
centres and scales the workspace; :func:`turned_rot6` turns goal orientations for the cycle
term; :func:`widens` and :func:`widened_state` start a model with a wider posture index from a
smaller one, or a pose model from a position model (``sik-train --init``, ``sik-build``).
"""

from dataclasses import replace
from typing import Dict, TYPE_CHECKING, Union

import numpy as np
from scipy.spatial.transform import Rotation
import torch

from sik_ros.errors import ArtifactMismatch
from sik_ros.learning.generated_data import GeneratedData
from sik_ros.learning.models import make_goal, ModelConfig, Normalizer
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


def widens(old: ModelConfig, new: ModelConfig) -> bool:
    """Whether ``new`` widens ``old``: a wider posture index, or a pose goal for a position one.

    A wider index has more learned elements or more branch bits (the old ones first); a pose
    model may start from a position model (its orientation inputs start at zero weight).
    """
    goals = new.goal == old.goal or (old.goal, new.goal) == ('position', 'pose')
    same = replace(new, goal=old.goal, latent_dim=old.latent_dim, branches=old.branches) == old
    return (same and goals and old.kind == 'sik' and new.latent_dim >= old.latent_dim
            and tuple(new.branches[:len(old.branches)]) == tuple(old.branches))


def first_layer_columns(old_cfg: ModelConfig, cfg: ModelConfig, part: str) -> np.ndarray:
    """Where each input of ``old_cfg``'s first ``part`` layer goes in ``cfg``'s (widened) one.

    The goal's entries keep their places (a position goal is a pose goal's first three); the
    encoder's joints and the decoder's learned index and branch bits follow the wider goal,
    the bits after the wider learned part.

    Args:
        old_cfg: the smaller model's config.
        cfg: the widened model's config (:func:`widens`).
        part: ``encoder`` or ``decoder``.

    Returns:
        The new column of each old input column, (old inputs,) integers.
    """
    og, ng = old_cfg.goal_dim, cfg.goal_dim
    goal = np.arange(og)
    if part == 'encoder':
        return np.concatenate([goal, ng + np.arange(cfg.dof)])
    learned = ng + np.arange(old_cfg.latent_dim)
    bits = ng + cfg.latent_dim + np.arange(len(old_cfg.branches))
    return np.concatenate([goal, learned, bits])


def widened_state(fresh: Dict, old: Dict, old_cfg: ModelConfig, cfg: ModelConfig) -> Dict:
    """``old`` weights in a widened model (``fresh``: its initial state dict; :func:`widens`).

    The first layers keep the old inputs' columns (:func:`first_layer_columns`); the new
    inputs' columns (orientation entries, learned elements, bits) are zero, so the widened
    model computes what the old one did. The encoder's last layer keeps its old outputs; new
    outputs take a tenth of their initial weights.
    """
    out = {k: v.clone() for k, v in fresh.items()}
    enc_last = 'encoder.%d.' % max(int(k.split('.')[1]) for k in old if k.startswith('encoder.'))
    for key, value in old.items():
        target = out[key]
        if key in ('encoder.0.weight', 'decoder.0.weight'):
            w = torch.zeros_like(target)
            cols = torch.as_tensor(first_layer_columns(old_cfg, cfg, key.split('.')[0]))
            if len(cols) != value.shape[1]:
                raise ArtifactMismatch(f'weights {key} of the smaller model',
                                       (target.shape[0], len(cols)), tuple(value.shape))
            w[:, cols] = value
            out[key] = w
        elif target.shape == value.shape:
            out[key] = value.clone()
        elif key.startswith(enc_last):
            w = target * 0.1
            w[:value.shape[0]] = value
            out[key] = w
        else:
            raise ArtifactMismatch(f'weights {key} of the smaller model', tuple(target.shape),
                                   tuple(value.shape))
    return out


def same_normalizer(a, b) -> bool:
    """Whether two normalisers scale alike (limits, position centre and scale, to 1e-6)."""
    mine = np.concatenate([a.lower, a.upper, a.position_center, [a.position_scale]])
    theirs = np.concatenate([b.lower, b.upper, b.position_center, [b.position_scale]])
    return bool(np.allclose(mine, theirs, rtol=1e-6, atol=1e-9))


def stream_states(gen: torch.Generator, sample_gen: torch.Generator) -> Dict:
    """A trainer's random streams as a checkpoint keeps them (torch's, the batches')."""
    out = {'torch': torch.get_rng_state(), 'batches': gen.get_state()}
    if sample_gen is not gen:
        out['device_batches'] = sample_gen.get_state()
    return out


def restore_streams(rng: Dict, gen: torch.Generator, sample_gen: torch.Generator, seed: int,
                    rank: int, step: int) -> None:
    """The streams of :func:`stream_states` set again, for ``rank`` at ``step``."""
    torch.set_rng_state(rng['torch'])
    gen.set_state(rng['batches'])
    if sample_gen is not gen:
        if 'device_batches' in rng:
            sample_gen.set_state(rng['device_batches'])
        else:  # a run resumed on a GPU: a stream of its own from here
            sample_gen.manual_seed(seed + 2 + step)
    if rank > 0:  # the checkpoint holds rank 0's stream: the others draw their own
        gen.manual_seed(seed + 1 + 7919 * rank + step)
        if sample_gen is not gen:
            sample_gen.manual_seed(seed + 2 + 7919 * rank + step)
