"""The loss terms beside the paper's joint reconstruction, and the validation's angle error.

Each is a function of tensors: the forward-kinematics term (:func:`fk_error`), the cycle term
of a posture index decoded at a moved goal (:func:`cycle_terms`) and the angle between two
rotations given by their first two columns (:func:`orientation_error_deg`).
"""

from typing import Dict

import torch

from sik_ros.learning.models import Normalizer, TorchChain
from sik_ros.learning.train_config import TrainConfig
from sik_ros.learning.training_data import turned_rot6


def fk_error(fk: TorchChain, norm: Normalizer, cfg: TrainConfig, pose: bool,
             x_hat: torch.Tensor, pos: torch.Tensor, rot6: torch.Tensor) -> torch.Tensor:
    """The FK term of normalised joints against their goals (batch mean).

    ``|FK(q) - p|^2 / fk_scale^2``, plus ``rot_weight`` times the squared difference of the
    first two rotation columns for pose goals.

    Args:
        fk: the arm's torch forward kinematics.
        norm: the model's normaliser.
        cfg: the training settings (``fk_scale`` [m], ``rot_weight``).
        pose: whether the goals are poses.
        x_hat: normalised joints (N, dof).
        pos: goal positions (N, 3) [m].
        rot6: goal rotations' first two columns (N, 6).
    """
    p_hat, r_hat = fk(norm.q_from_net(x_hat))
    err = ((p_hat - pos) ** 2).sum(1).mean() / cfg.fk_scale ** 2
    if pose:
        r6 = torch.cat([r_hat[:, :, 0], r_hat[:, :, 1]], 1)
        err = err + cfg.rot_weight * ((r6 - rot6) ** 2).sum(1).mean()
    return err


def cycle_terms(model: torch.nn.Module, norm: Normalizer, cfg: TrainConfig, pose: bool,
                mu: torch.Tensor, pos: torch.Tensor, rot6: torch.Tensor,
                gen: torch.Generator) -> Dict[str, torch.Tensor]:
    """The cycle term: each index decoded at its goal moved by about ``cycle_shift``.

    The table's use of the model: an index found at a nearby position decoded at the goal. The
    posture must re-encode to the same index there (so the decoder cannot ignore the index);
    the goal is also turned by about ``cycle_turn`` for pose goals.

    Returns:
        ``cycle`` (the squared index error over the batch's index variance), and the moved
        goals' ``x_other`` (normalised joints), ``pos_other`` and ``rot6_other`` for the FK term.
    """
    shift = torch.randn(len(pos), 3, generator=gen, device=pos.device)
    pos_other = pos + cfg.cycle_shift * shift
    rot6_other = rot6
    if pose and cfg.cycle_turn > 0:
        rot6_other = turned_rot6(rot6, cfg.cycle_turn, gen)
    goal_other = torch.cat([pos_other, rot6_other], 1) if pose else pos_other
    g_other = norm.goal_to_net(goal_other)
    z = mu.detach()
    x_other = model.decode(g_other, z)
    z_back, _ = model.encode(g_other, x_other)
    spread = z.var(dim=0).sum().clamp_min(1e-8)
    return {'cycle': ((z_back - z) ** 2).sum(1).mean() / spread, 'x_other': x_other,
            'pos_other': pos_other, 'rot6_other': rot6_other}


def orientation_error_deg(rot6: torch.Tensor, r_hat: torch.Tensor) -> torch.Tensor:
    """Angle [deg] between goal rotations (first two columns, (N, 6)) and rotations (N, 3, 3)."""
    r = torch.stack([rot6[:, :3], rot6[:, 3:],
                     torch.linalg.cross(rot6[:, :3], rot6[:, 3:])], dim=2)
    rel = r.transpose(1, 2) @ r_hat
    cos = ((rel.diagonal(dim1=1, dim2=2).sum(1) - 1) / 2).clamp(-1, 1)
    return torch.rad2deg(torch.arccos(cos))
