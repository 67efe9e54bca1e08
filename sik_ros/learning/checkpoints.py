"""Checkpoints on disk: reading, checking, rebuilding a model from one, exporting one.

Inference (the solver, index tables, bundles, the node) loads models through this module and
never imports :mod:`sik_ros.learning.training`.
"""

import hashlib
import json
from pathlib import Path
from typing import Dict

import torch

from sik_ros.artifacts import atomic_write, FORMAT_VERSION
from sik_ros.errors import ArtifactMismatch, CorruptArtifact
from sik_ros.learning.model_config import normalizer_from_dict  # noqa: F401 (API)
from sik_ros.learning.models import build_model, ModelConfig


def load_checkpoint(path: Path) -> Dict:
    """Read and check a checkpoint (or exported model) file.

    Raises:
        CorruptArtifact: unreadable, truncated, or not a sik_ros checkpoint.
    """
    path = Path(path)
    if not path.is_file():
        raise CorruptArtifact(f'checkpoint {path} does not exist')
    try:
        ckpt = torch.load(path, map_location='cpu', weights_only=True)
    except Exception as exc:  # torch raises many types for a damaged file
        raise CorruptArtifact(f'cannot read checkpoint {path}: {exc}') from exc
    if not isinstance(ckpt, dict) or ckpt.get('kind') not in ('sik_checkpoint', 'sik_model'):
        raise CorruptArtifact(f'{path} is not a sik_ros checkpoint')
    if ckpt.get('format_version') != FORMAT_VERSION:
        raise ArtifactMismatch(f'{path} format version', FORMAT_VERSION,
                               ckpt.get('format_version'))
    for key in ('model_config', 'normalizer', 'robot', 'model_state'):
        if key not in ckpt:
            raise CorruptArtifact(f'checkpoint {path} lacks {key!r}')
    return ckpt


def model_from_checkpoint(ckpt: Dict):
    """Rebuild ``(module in eval mode, ModelConfig, Normalizer)`` from a checkpoint dict."""
    cfg = ModelConfig.from_dict(ckpt['model_config'])
    model = build_model(cfg)
    try:
        model.load_state_dict(ckpt['model_state'])
    except RuntimeError as exc:
        raise CorruptArtifact(f'checkpoint weights do not fit its config: {exc}') from exc
    model.eval()
    return model, cfg, normalizer_from_dict(ckpt['normalizer'])


def export_model(ckpt: Dict, path: Path) -> Path:
    """Write the inference part of a checkpoint (no optimiser) atomically to ``path``."""
    keep = ('model_config', 'train_config', 'normalizer', 'robot', 'dataset', 'model_state',
            'step', 'elapsed_s', 'history', 'versions', 'trained')
    out = {k: ckpt[k] for k in keep if k in ckpt}
    out.update(kind='sik_model', format_version=FORMAT_VERSION)
    with atomic_write(path) as tmp:
        torch.save(out, tmp)
    return Path(path)


def model_signature(ckpt: Dict) -> Dict:
    """What ties a table to the model that encoded it."""
    digest = hashlib.sha256()
    for name, tensor in sorted(ckpt['model_state'].items()):
        digest.update(name.encode())
        digest.update(tensor.detach().cpu().contiguous().numpy().tobytes())
    sig = {'model_config': ckpt['model_config'], 'step': int(ckpt.get('step', 0)),
           'weights_sha256': digest.hexdigest()}
    return json.loads(json.dumps(sig))
