"""Warm starts: a model that starts from another model's weights (``sik-train --init``).

Four starts besides the same model's weights: a SIK model with a wider posture index from a
smaller one, a pose model from a position model (:func:`widened_state`: the new inputs start at
zero weight, so the new model computes what the old one did), a SIK model with a smaller,
fresh index from one with a larger index (:func:`narrowed_state`: a pose model of a 1-element
index from a position model of 4 keeps the trunks of both networks and learns its index
afresh), and a PSIK model from a SIK model of the same layers (:func:`variational_state`: the
encoder's index becomes the mean, a log-variance head is added at a small variance, and
:func:`standardise_index` rescales the index to zero mean and unit spread over the training
rows so that the KL term starts near its floor).
"""

from dataclasses import asdict, replace
from typing import Dict, Optional

import numpy as np
import torch

from sik_ros.errors import ArtifactMismatch
from sik_ros.learning.models import ModelConfig

#: Log-variance [log of normalised index units squared] a PSIK started from SIK begins with:
#: a standard deviation of 0.05, small beside the index's unit spread, so the first steps'
#: sampled indices decode as the SIK model's do.
PSIK_LOGVAR_START = -6.0


def widens(old: ModelConfig, new: ModelConfig) -> bool:
    """Whether ``new`` widens ``old``: a wider posture index, or a pose goal for a position one.

    A wider index has more learned elements or more branch bits (the old ones first); a pose
    model may start from a position model (its orientation inputs start at zero weight).
    """
    goals = new.goal == old.goal or (old.goal, new.goal) == ('position', 'pose')
    same = replace(new, goal=old.goal, latent_dim=old.latent_dim, branches=old.branches) == old
    return (same and goals and old.kind == 'sik' and new.latent_dim >= old.latent_dim
            and tuple(new.branches[:len(old.branches)]) == tuple(old.branches))


def narrows(old: ModelConfig, new: ModelConfig) -> bool:
    """Whether ``new`` is ``old`` with a smaller learned index (and maybe a pose goal).

    The layers are the same; the goal the same or a pose goal for a position one; ``old``'s
    branch bits (if any) come first in ``new``'s. The new index is learned afresh
    (:func:`narrowed_state`).
    """
    goals = new.goal == old.goal or (old.goal, new.goal) == ('position', 'pose')
    same = replace(new, goal=old.goal, latent_dim=old.latent_dim, branches=old.branches) == old
    return (same and goals and old.kind == 'sik' and new.latent_dim < old.latent_dim
            and tuple(new.branches[:len(old.branches)]) == tuple(old.branches))


def makes_variational(old: ModelConfig, new: ModelConfig) -> bool:
    """Whether ``new`` is the PSIK of SIK model ``old``: the same goal, index and layers."""
    return old.kind == 'sik' and new.kind == 'psik' and replace(new, kind='sik') == old


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


def _last_encoder_layer(state: Dict) -> str:
    """The key prefix of the encoder's output layer in a state dict (``encoder.N.``)."""
    return 'encoder.%d.' % max(int(k.split('.')[1]) for k in state if k.startswith('encoder.'))


def widened_state(fresh: Dict, old: Dict, old_cfg: ModelConfig, cfg: ModelConfig) -> Dict:
    """``old`` weights in a widened model (``fresh``: its initial state dict; :func:`widens`).

    The first layers keep the old inputs' columns (:func:`first_layer_columns`); the new
    inputs' columns (orientation entries, learned elements, bits) are zero, so the widened
    model computes what the old one did. The encoder's last layer keeps its old outputs; new
    outputs take a tenth of their initial weights.
    """
    out = {k: v.clone() for k, v in fresh.items()}
    enc_last = _last_encoder_layer(old)
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


def narrowed_state(fresh: Dict, old: Dict, old_cfg: ModelConfig, cfg: ModelConfig,
                   index_mean: np.ndarray) -> Dict:
    """``old`` weights in a model of a smaller, fresh index (``fresh``: its initial state dict).

    Every hidden layer is the old one; the first layers keep the goal's (and the encoder's
    joints') columns, the new goal entries (orientation) start at zero weight, and the old
    model's branch bits keep theirs. The old learned index leaves the decoder at its mean
    (``index_mean``, over training rows: its columns' effect there goes into the bias), so that
    with the new index at zero weight the decoder gives the old model's posture at the mean
    index. The new index is fresh: the encoder's output layer and the decoder's index columns
    keep their initial weights.

    Args:
        fresh: the new model's initial state dict.
        old: the old model's state dict.
        old_cfg: the old model's config.
        cfg: the new model's config (:func:`narrows`).
        index_mean: the old model's mean learned index over training rows, (old latent,).
    """
    out = {k: v.clone() for k, v in fresh.items()}
    enc_last = _last_encoder_layer(old)
    og, ng = old_cfg.goal_dim, cfg.goal_dim
    for key, value in old.items():
        if key.startswith(enc_last):
            continue  # the new index's output layer stays fresh
        target = out[key]
        if key == 'encoder.0.weight':
            w = torch.zeros_like(target)
            w[:, torch.as_tensor(first_layer_columns(old_cfg, cfg, 'encoder'))] = value
            out[key] = w
        elif key == 'decoder.0.weight':
            w = torch.zeros_like(target)
            w[:, :og] = value[:, :og]
            learned = slice(ng, ng + cfg.latent_dim)
            w[:, learned] = target[:, learned]
            bits = len(old_cfg.branches)
            start = ng + cfg.latent_dim
            w[:, start:start + bits] = value[:, og + old_cfg.latent_dim:]
            out[key] = w
            mean = torch.as_tensor(np.asarray(index_mean), dtype=value.dtype)
            out['decoder.0.bias'] = (old['decoder.0.bias']
                                     + value[:, og:og + old_cfg.latent_dim] @ mean)
        elif key == 'decoder.0.bias':
            continue  # set with the weights
        elif target.shape == value.shape:
            out[key] = value.clone()
        else:
            raise ArtifactMismatch(f'weights {key} of the larger model', tuple(target.shape),
                                   tuple(value.shape))
    return out


def variational_state(old: Dict, latent_dim: int,
                      logvar: float = PSIK_LOGVAR_START) -> Dict:
    """A SIK model's weights as a PSIK's (:func:`makes_variational`).

    The encoder's output layer keeps SIK's index as the mean and gains a log-variance head:
    zero weights and a bias of ``logvar``, a variance the same at every input.
    """
    out = {k: v.clone() for k, v in old.items()}
    enc_last = _last_encoder_layer(old)
    w, b = old[enc_last + 'weight'], old[enc_last + 'bias']
    if w.shape[0] != latent_dim:
        raise ArtifactMismatch('index size of the SIK model', latent_dim, w.shape[0])
    out[enc_last + 'weight'] = torch.cat([w, torch.zeros_like(w)], 0)
    out[enc_last + 'bias'] = torch.cat([b, torch.full_like(b, logvar)], 0)
    return out


@torch.no_grad()
def standardise_index(model: torch.nn.Module, goal: torch.Tensor,
                      x: torch.Tensor) -> Dict[str, np.ndarray]:
    """Rescale a PSIK model's index to zero mean and unit spread per element, in place.

    The mean ``m`` and standard deviation ``s`` of the encoder's means over the given rows are
    folded into the encoder's output layer (the mean becomes ``(mu - m) / s``) and the
    decoder's first layer (its index columns take ``s`` and its bias the effect of ``m``): the
    decoder's output for each row's own mean is unchanged, up to rounding.

    Args:
        model: a PSIK model (:class:`~sik_ros.learning.models.SIK`, variational).
        goal: normalised goals (N, goal entries).
        x: normalised joints (N, dof).

    Returns:
        ``{'mean': m, 'std': s}`` of the index before, per element.
    """
    mu, _ = model.encode(goal, x)
    m, s = mu.mean(0), mu.std(0).clamp_min(1e-6)
    k = len(m)
    enc = model.encoder[-1]
    enc.weight[:k] /= s[:, None]
    enc.bias[:k] = (enc.bias[:k] - m) / s
    dec = model.decoder[0]
    cols = slice(goal.shape[1], goal.shape[1] + k)
    dec.bias += dec.weight[:, cols] @ m
    dec.weight[:, cols] *= s[None, :]
    return {'mean': m.numpy(), 'std': s.numpy()}


def initial_state(fresh: Dict, ckpt: Dict, cfg: ModelConfig, source: str,
                  index_mean: Optional[np.ndarray] = None) -> Dict:
    """The state dict a model of ``cfg`` starts from, given another model's checkpoint.

    Args:
        fresh: the new model's initial state dict.
        ckpt: the checkpoint (or exported model) to start from.
        cfg: the new model's config.
        source: where the checkpoint came from (for messages).
        index_mean: the checkpoint's mean learned index over training rows (a narrowed
            start, :func:`narrows`; zero if not given).

    Raises:
        ArtifactMismatch: a model neither the same, nor widened (:func:`widens`), nor
            narrowed (:func:`narrows`), nor made variational (:func:`makes_variational`).
    """
    found = ModelConfig.from_dict(ckpt['model_config'])
    state = ckpt['model_state']
    if found == cfg:
        return state
    if makes_variational(found, cfg):
        return variational_state(state, cfg.latent_dim)
    if widens(found, cfg):
        return widened_state(fresh, state, found, cfg)
    if narrows(found, cfg):
        mean = np.zeros(found.latent_dim) if index_mean is None else index_mean
        return narrowed_state(fresh, state, found, cfg, mean)
    raise ArtifactMismatch(f'--init {source} model config', asdict(cfg), ckpt['model_config'])


@torch.no_grad()
def index_mean(ckpt: Dict, goal: torch.Tensor, q: torch.Tensor) -> np.ndarray:
    """The mean learned index of a checkpoint's model over rows (goals, joints; its units)."""
    from sik_ros.learning.checkpoints import normalizer_from_dict
    from sik_ros.learning.models import build_model
    old_cfg = ModelConfig.from_dict(ckpt['model_config'])
    old = build_model(old_cfg)
    old.load_state_dict(ckpt['model_state'])
    norm = normalizer_from_dict(ckpt['normalizer'])
    z, _ = old.encode(norm.goal_to_net(goal)[:, :old_cfg.goal_dim], norm.q_to_net(q))
    return z[:, :old_cfg.latent_dim].mean(0).numpy()


def checked_normalizer(ckpt: Dict, mine, source: str, same_data: bool):
    """The normaliser of a warm start's weights, bit for bit the one they were trained with.

    With ``same_data`` (a dataset, not rows generated afresh) it must equal ``mine`` (the
    dataset's): weights trained on another dataset are refused.
    """
    from sik_ros.learning.checkpoints import normalizer_from_dict
    norm = normalizer_from_dict(ckpt['normalizer'])
    if same_data:
        a = np.concatenate([mine.lower, mine.upper, mine.position_center,
                            [mine.position_scale]])
        b = np.concatenate([norm.lower, norm.upper, norm.position_center,
                            [norm.position_scale]])
        if not np.allclose(a, b, rtol=1e-6, atol=1e-9):
            raise ArtifactMismatch(f'--init {source} normaliser (another dataset)',
                                   asdict(mine), ckpt['normalizer'])
    return norm
