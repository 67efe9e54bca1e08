"""Neural models: SIK (auto-encoder), PSIK (conditional VAE), and the paper's FCN and ANFIS.

Joint angles are normalised to [-1, 1] by their limits; goal positions are divided by a workspace
scale. A ``pose`` goal is the position plus the first two columns of the tip rotation matrix (a
continuous 6-d orientation representation).
"""

import math
from typing import Tuple

import numpy as np
import torch
from torch import nn

from sik_ros.defaults import (DEFAULT_LATENT, GOAL_KINDS, MODEL_KINDS,  # noqa: F401 (API)
                              PRESETS)
from sik_ros.kinematics.chain import chain_forward, SerialChain
from sik_ros.learning.model_config import (make_goal, ModelConfig,  # noqa: F401 (API)
                                           Normalizer, rotation_goal)


def mlp(sizes, out: int) -> nn.Sequential:
    """Fully connected layers with ELU after every layer but the output."""
    layers = []
    for a, b in zip(sizes[:-1], sizes[1:]):
        layers += [nn.Linear(a, b), nn.ELU()]
    layers.append(nn.Linear(sizes[-1], out))
    return nn.Sequential(*layers)


class TorchChain(nn.Module):
    """Differentiable forward kinematics of a :class:`SerialChain` in torch."""

    def __init__(self, chain: SerialChain, dtype: torch.dtype = torch.float32):
        super().__init__()
        for name in ('joint_rotations', 'joint_translations', 'axes', 'base_rotation',
                     'base_translation', 'tip_rotation', 'tip_translation'):
            self.register_buffer(name, torch.as_tensor(getattr(chain, name), dtype=dtype),
                                 persistent=False)

    def forward(self, q: torch.Tensor) -> Tuple[torch.Tensor, torch.Tensor]:
        """Tip positions (N, 3) [m] and rotations (N, 3, 3) of joint positions (N, n) [rad]."""
        return chain_forward(self, q, xp=torch)


class SIK(nn.Module):
    """Selective IK: encoder (goal, q) -> posture index; decoder (goal, index) -> q.

    With ``variational`` (PSIK) the encoder outputs a mean and a log-variance and the index is
    sampled with the reparameterisation trick while training.
    """

    def __init__(self, cfg: ModelConfig):
        super().__init__()
        self.cfg = cfg
        self.variational = cfg.kind == 'psik'
        out = cfg.latent_dim * (2 if self.variational else 1)
        self.encoder = mlp((cfg.goal_dim + cfg.dof,) + cfg.encoder, out)
        self.decoder = mlp((cfg.goal_dim + cfg.index_dim,) + cfg.decoder, cfg.dof)
        bits = np.array(cfg.branches, dtype=np.float32).reshape(-1, 3)
        self.register_buffer('branch_joint', torch.as_tensor(bits[:, 0].astype(np.int64)),
                             persistent=False)
        self.register_buffer('branch_affine', torch.as_tensor(bits[:, 1:]), persistent=False)

    def branch_code(self, x: torch.Tensor) -> torch.Tensor:
        """The branch bits (N, bits) of normalised joints, each -1 or 1."""
        a = self.branch_affine.to(x.dtype)
        s = torch.sin(x[:, self.branch_joint] * a[:, 0] + a[:, 1])
        return torch.where(s < 0, -torch.ones_like(s), torch.ones_like(s))

    def encode(self, goal: torch.Tensor, x: torch.Tensor):
        """Posture index (mean) and log-variance (None for SIK) of normalised (goal, joints).

        With a branch code the index is the encoder's output followed by the bits.
        """
        h = self.encoder(torch.cat([goal, x], dim=1))
        if self.variational:
            mu, logvar = h.chunk(2, dim=1)
            return mu, logvar.clamp(-12.0, 8.0)
        if len(self.cfg.branches):
            h = torch.cat([h, self.branch_code(x)], dim=1)
        return h, None

    def decode(self, goal: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
        """Normalised joints from a normalised goal and a posture index."""
        return self.decoder(torch.cat([goal, z], dim=1))

    def forward(self, goal: torch.Tensor, x: torch.Tensor):
        """Reconstruction, index, and log-variance (None for SIK)."""
        mu, logvar = self.encode(goal, x)
        z = mu
        if self.variational and self.training:
            z = mu + torch.randn_like(mu) * torch.exp(0.5 * logvar)
        return self.decode(goal, z), mu, logvar


def branch_bits(chain: SerialChain, lower: np.ndarray, upper: np.ndarray,
                offset: float = 0.1, edge: float = 0.05) -> Tuple[Tuple[int, float, float], ...]:
    """The branch code of an arm: its flip joints, as :attr:`ModelConfig.branches`.

    A joint whose two neighbours' axes line up (parallel and within ``offset`` [m] of each
    other) at some angle ``s`` is a flip joint (a 7-joint arm's shoulder and wrist, a UR arm's
    wrist): ``q`` and its mirror about ``s`` lie on separate pieces of the self-motion of a
    pose, which one continuous index cannot tell apart. The bit is the sign of ``sin(q - s)``;
    it counts when ``sin(q - s)`` changes sign inside the joint's limits (away from the last
    ``edge`` of the range at either end). The angles are taken with the other joints at zero,
    which does not matter: the angle between a joint's neighbours depends on that joint alone.

    Args:
        chain: the arm's chain.
        lower: joint lower limits (n,) [rad].
        upper: joint upper limits (n,) [rad].
        offset: farthest the lined-up axes may be apart [m].
        edge: fraction of a joint's range at either end where a crossing does not count.

    Returns:
        ``(joint, scale, offset)`` per bit, in the networks' normalised joint units.
    """
    n = chain.dof
    t = np.linspace(-np.pi, np.pi, 721)
    bits = []
    for j in range(1, n - 1):
        q = np.zeros((len(t), n))
        q[:, j] = t
        _, _, o, a = chain_forward(chain, q, frames=True)
        off = 1 - np.abs((a[:, j - 1] * a[:, j + 1]).sum(1))
        if off.max() < 1e-6:  # always parallel: no flip at one angle
            continue
        dist = np.linalg.norm(np.cross(o[:, j + 1] - o[:, j - 1], a[:, j - 1]), axis=1)
        hits = np.flatnonzero((off < 1e-6) & (dist <= offset))
        if not len(hits):
            continue
        s = float(t[hits[0]])
        lo, hi = float(lower[j]), float(upper[j])
        margin = edge * (hi - lo)
        # the multiples of pi from s strictly inside the limits, where the sign changes
        first = math.ceil((lo + margin - s) / math.pi)
        last = math.floor((hi - margin - s) / math.pi)
        if last < first:
            continue
        mid, half = (lo + hi) / 2, (hi - lo) / 2
        bits.append((j, half, mid - s))
    return tuple(bits)


def kl_normal(mu: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """KL(N(mu, exp(logvar)) || N(0, I)) per sample, closed form, summed over dimensions."""
    return -0.5 * torch.sum(1 + logvar - mu.pow(2) - logvar.exp(), dim=1)


class FCN(nn.Module):
    """The paper's baseline: a fully connected net goal -> joints, shaped like the decoder."""

    def __init__(self, cfg: ModelConfig):
        super().__init__()
        self.cfg = cfg
        self.net = mlp((cfg.goal_dim,) + cfg.decoder, cfg.dof)

    def forward(self, goal: torch.Tensor) -> torch.Tensor:
        """Normalised joints from a normalised goal."""
        return self.net(goal)


class ANFIS(nn.Module):
    """First-order Sugeno fuzzy inference, ``anfis_mfs`` generalised-bell MFs per input.

    Parameters are kept in one flat vector so a particle swarm can optimise them
    (:func:`anfis_forward` evaluates many parameter vectors at once).
    """

    def __init__(self, cfg: ModelConfig):
        super().__init__()
        self.cfg = cfg
        self.params_flat = nn.Parameter(anfis_initial(cfg))

    def forward(self, goal: torch.Tensor) -> torch.Tensor:
        """Normalised joints from a normalised goal."""
        return anfis_forward(self.cfg, self.params_flat[None], goal)[0]


def anfis_sizes(cfg: ModelConfig) -> Tuple[int, int, int]:
    """(inputs, rules, parameter count) of an ANFIS."""
    d, m = cfg.goal_dim, cfg.anfis_mfs
    rules = m ** d
    return d, rules, d * m * 3 + rules * (d + 1) * cfg.dof


def anfis_initial(cfg: ModelConfig) -> torch.Tensor:
    """Evenly spread bell MFs over [-1, 1] and zero consequents."""
    d, rules, total = anfis_sizes(cfg)
    m = cfg.anfis_mfs
    centers = torch.linspace(-1, 1, m).repeat(d)
    widths = torch.full((d * m,), 2.0 / m)
    slopes = torch.full((d * m,), 2.0)
    return torch.cat([centers, widths, slopes, torch.zeros(rules * (d + 1) * cfg.dof)])


def anfis_forward(cfg: ModelConfig, params: torch.Tensor, goal: torch.Tensor) -> torch.Tensor:
    """Evaluate P parameter vectors (P, K) on goals (N, d): outputs (P, N, dof)."""
    d, rules, _ = anfis_sizes(cfg)
    m = cfg.anfis_mfs
    p = params.shape[0]
    c = params[:, :d * m].reshape(p, d, m)
    a = params[:, d * m:2 * d * m].reshape(p, d, m).abs() + 1e-3
    b = params[:, 2 * d * m:3 * d * m].reshape(p, d, m)
    coef = params[:, 3 * d * m:].reshape(p, rules, d + 1, cfg.dof)
    x = goal[None, :, :, None]                                          # (1, N, d, 1)
    mu = 1.0 / (1.0 + ((x - c[:, None]) / a[:, None]).abs().pow(2 * b[:, None].abs()))
    idx = torch.cartesian_prod(*[torch.arange(m)] * d).reshape(rules, d)  # rule -> MF per input
    w = torch.ones(p, goal.shape[0], rules, dtype=goal.dtype, device=goal.device)
    for k in range(d):
        w = w * mu[:, :, k, idx[:, k]]
    w = w / (w.sum(dim=2, keepdim=True) + 1e-12)
    xa = torch.cat([goal, torch.ones_like(goal[:, :1])], dim=1)         # (N, d+1)
    f = torch.einsum('nd,prdo->pnro', xa, coef)                         # (P, N, R, dof)
    return torch.einsum('pnr,pnro->pno', w, f)


def build_model(cfg: ModelConfig) -> nn.Module:
    """The module for a model config."""
    if cfg.kind in ('sik', 'psik'):
        return SIK(cfg)
    if cfg.kind == 'fcn':
        return FCN(cfg)
    return ANFIS(cfg)
