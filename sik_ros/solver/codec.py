"""The networks at a goal: posture indices decoded to joints, joints encoded to indices.

A solve decodes and encodes a few rows at a time, where a torch call costs more in overhead
than in arithmetic; the SIK networks (linear layers and ELUs) are therefore run as NumPy
float32 matrix products on their own weights (:class:`NumpyMLP`; the same outputs as torch's
to float32 rounding), a few rows in one compiled call (:func:`sik_ros.kernels.mlp.mlp_rows`),
and other models through torch.
"""

from typing import List, Optional, Tuple
import weakref

import numpy as np

from sik_ros.kernels import as_arg, mlp_rows, pack_layers
from sik_ros.learning.model_config import make_goal
from sik_ros.learning.twins import NumpySIK, torch_layers
from sik_ros.solver.config import KERNEL_ROWS
from sik_ros.solver.context import Context, Goal


class NumpyMLP:
    """A torch ``Sequential`` of ``Linear`` and ``ELU`` layers, evaluated with NumPy."""

    def __init__(self, layers: List[Tuple[np.ndarray, np.ndarray]]):
        self.layers = layers
        self._packed = pack_layers(layers)

    @staticmethod
    def of(seq) -> Optional['NumpyMLP']:
        """The NumPy twin of a torch ``seq``, or None when it holds other layers."""
        layers = torch_layers(seq)
        return None if layers is None else NumpyMLP(layers)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """The outputs (M, out) of float32 inputs (M, in)."""
        if len(x) <= KERNEL_ROWS:
            return mlp_rows(as_arg(x, np.float32), *self._packed)
        last = len(self.layers) - 1
        for i, (w, b) in enumerate(self.layers):
            x = x @ w
            x += b
            if i < last:
                # ELU: expm1(x) >= x, so max(x, expm1(min(x, 0))) is x above 0 and expm1(x)
                # below, in place (cheaper than np.where on the two)
                m = np.minimum(x, 0)
                np.expm1(m, out=m)
                x = np.maximum(x, m, out=m)
        return x


_TWINS: 'weakref.WeakKeyDictionary' = weakref.WeakKeyDictionary()


def _twins(model):
    """(encoder, decoder) NumPy twins of an SIK model, or None (made once per model).

    A bundle's twin (:class:`NumpySIK`, loaded without torch) is its own.
    """
    if model not in _TWINS:
        twins = None
        if isinstance(model, NumpySIK):
            twins = (NumpyMLP(model.encoder), NumpyMLP(model.decoder))
        else:  # a torch module: torch is loaded already
            from sik_ros.learning.models import SIK
            if isinstance(model, SIK):
                enc, dec = NumpyMLP.of(model.encoder), NumpyMLP.of(model.decoder)
                if enc is not None and dec is not None:
                    twins = (enc, dec)
        _TWINS[model] = twins
    return _TWINS[model]


def _goal_rows(ctx: Context, goal: Goal, rows: int) -> np.ndarray:
    """The goal in the network's normalised units, float32 (rows, goal_dim)."""
    norm = ctx.models[goal.kind].norm
    g = make_goal(goal.kind, goal.position[None],
                  None if goal.rotation is None else goal.rotation[None])[0].astype(np.float64)
    g[:3] = (g[:3] - np.asarray(norm.position_center)) / norm.position_scale
    return np.repeat(g.astype(np.float32)[None], rows, 0)


def _limits(ctx: Context, goal: Goal) -> Tuple[np.ndarray, np.ndarray]:
    norm = ctx.models[goal.kind].norm
    lo = np.asarray(norm.lower, dtype=np.float32)
    hi = np.asarray(norm.upper, dtype=np.float32)
    return (lo + hi) / 2, (hi - lo) / 2


def goal_net(ctx: Context, goal: Goal, rows: int):
    """The goal repeated ``rows`` times, in the network's normalised units (a torch tensor)."""
    import torch
    g = make_goal(goal.kind, np.repeat(goal.position[None], rows, 0),
                  None if goal.rotation is None else np.repeat(goal.rotation[None], rows, 0))
    return ctx.models[goal.kind].norm.goal_to_net(torch.from_numpy(g.astype(np.float32)))


def decode(ctx: Context, goal: Goal, z: np.ndarray) -> np.ndarray:
    """Joint solutions (M, n) [rad] decoded from posture indices (M, latent), clipped.

    With no learned model (:mod:`~sik_ros.bundles.sweep_models`) an index is a configuration.
    """
    gm = ctx.models[goal.kind]
    if gm.model is None:
        return np.clip(np.asarray(z, dtype=np.float64), ctx.robot.lower, ctx.robot.upper)
    twins = _twins(gm.model)
    z = np.asarray(z, dtype=np.float32)
    if len(z) == 0:
        return np.empty((0, ctx.robot.dof))
    if twins is None:
        import torch
        with torch.no_grad():
            x = gm.model.decode(goal_net(ctx, goal, len(z)), torch.from_numpy(z))
            q = gm.norm.q_from_net(x).double().numpy()
    else:
        centre, half = _limits(ctx, goal)
        x = twins[1](np.concatenate([_goal_rows(ctx, goal, len(z)), z], axis=1))
        q = (x * half + centre).astype(np.float64)
    return np.clip(q, ctx.robot.lower, ctx.robot.upper)


def encode(ctx: Context, goal: Goal, q: np.ndarray) -> np.ndarray:
    """Posture indices (M, latent) of configurations (M, n) for a goal (no model: ``q``)."""
    gm = ctx.models[goal.kind]
    if gm.model is None:
        return np.array(q, dtype=np.float64)
    twins = _twins(gm.model)
    if twins is None:
        import torch
        with torch.no_grad():
            z, _ = gm.model.encode(goal_net(ctx, goal, len(q)),
                                   gm.norm.q_to_net(torch.from_numpy(q.astype(np.float32))))
        return z.numpy().astype(np.float64)
    centre, half = _limits(ctx, goal)
    x = (q.astype(np.float32) - centre) / half
    h = twins[0](np.concatenate([_goal_rows(ctx, goal, len(q)), x], axis=1))
    z = h[:, :gm.model.cfg.latent_dim].astype(np.float64)
    if gm.model.cfg.branches:
        z = np.concatenate([z, branch_code(gm.model.cfg.branches, x)], axis=1)
    return z


def branch_code(branches, x: np.ndarray) -> np.ndarray:
    """The branch bits (M, bits) of normalised joints (M, n), as :meth:`SIK.branch_code`."""
    b = np.asarray(branches, dtype=np.float64).reshape(-1, 3)
    s = np.sin(x[:, b[:, 0].astype(int)] * b[:, 1] + b[:, 2])
    return np.where(s < 0, -1.0, 1.0)


def branch_codes(branches) -> np.ndarray:
    """Every combination of the branch bits, (2 ** bits, bits) (one empty row: none)."""
    n = len(branches)
    if n == 0:
        return np.zeros((1, 0))
    grid = (np.arange(2 ** n)[:, None] >> np.arange(n)[None]) & 1
    return np.where(grid > 0, 1.0, -1.0)
