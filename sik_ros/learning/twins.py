"""A SIK model's NumPy twin on disk: its layers as arrays, loaded without torch.

The solver runs SIK networks as NumPy matrix products on their own weights
(:mod:`sik_ros.solver.codec`); a twin file (``.npz``) holds those weights and what the model's
checkpoint says of itself (its config, normaliser, robot and weights' signature), so that a
bundle loads and serves without importing torch: a node starts about a second sooner
(docs/design.md, "An arm from robot_description"). :func:`write_twin` makes one from a
checkpoint (torch needed there); :func:`load_twin` reads it back, checked.
"""

import json
from pathlib import Path
from typing import Dict, List, Optional, Tuple
import zipfile

import numpy as np

from sik_ros.artifacts import atomic_write, FORMAT_VERSION
from sik_ros.errors import CorruptArtifact
from sik_ros.learning.model_config import ModelConfig, Normalizer, normalizer_from_dict

#: The manifest's ``kind``.
KIND = 'sik_twin'
Layers = List[Tuple[np.ndarray, np.ndarray]]


class NumpySIK:
    """A SIK model as its encoder's and decoder's layers ``(weight (in, out), bias (out,))``.

    Attributes:
        cfg: its :class:`ModelConfig`.
        encoder: the encoder's layers (ELU between them).
        decoder: the decoder's layers.
    """

    def __init__(self, cfg: ModelConfig, encoder: Layers, decoder: Layers):
        self.cfg, self.encoder, self.decoder = cfg, encoder, decoder


def torch_layers(seq) -> Optional[Layers]:
    """A torch ``Sequential`` of ``Linear`` and ``ELU`` layers as arrays, or None."""
    import torch
    mods = list(seq.children()) if isinstance(seq, torch.nn.Sequential) else []
    linear = mods[0::2]
    if not mods or len(mods) % 2 == 0 or not all(
            isinstance(m, torch.nn.Linear) for m in linear) or not all(
            isinstance(m, torch.nn.ELU) and m.alpha == 1.0 for m in mods[1::2]):
        return None
    return [(m.weight.detach().numpy().T.astype(np.float32),
             m.bias.detach().numpy().astype(np.float32)) for m in linear]


def write_twin(ckpt: Dict, path: Path) -> Optional[Path]:
    """Write a checkpoint's NumPy twin to ``path`` (atomically); None for a model without one.

    Only SIK models whose encoder and decoder are plain ``Linear``/``ELU`` stacks have one.
    """
    from sik_ros.learning.checkpoints import model_from_checkpoint, model_signature
    from sik_ros.learning.models import SIK
    model, cfg, _ = model_from_checkpoint(ckpt)
    if not isinstance(model, SIK) or cfg.kind != 'sik':
        return None
    enc, dec = torch_layers(model.encoder), torch_layers(model.decoder)
    if enc is None or dec is None:
        return None
    manifest = {'kind': KIND, 'format_version': FORMAT_VERSION,
                'model_config': ckpt['model_config'], 'normalizer': ckpt['normalizer'],
                'robot': ckpt['robot'], 'signature': model_signature(ckpt),
                'layers': [len(enc), len(dec)]}
    arrays = {f'{part}_{kind}{i}': a for part, layers in (('enc', enc), ('dec', dec))
              for i, (w, b) in enumerate(layers) for kind, a in (('w', w), ('b', b))}
    with atomic_write(Path(path)) as tmp:
        np.savez(tmp, manifest=np.array(json.dumps(manifest, sort_keys=True)), **arrays)
    return Path(path)


def load_twin(path: Path) -> Tuple[NumpySIK, ModelConfig, Normalizer, Dict]:
    """A twin's model, config, normaliser and manifest (its ``robot`` and ``signature``).

    Raises:
        CorruptArtifact: unreadable, or its arrays disagree with its manifest.
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as f:
            manifest = json.loads(str(f['manifest']))
            counts = manifest['layers']
            layers = [[(f[f'{part}_w{i}'], f[f'{part}_b{i}']) for i in range(int(n))]
                      for part, n in zip(('enc', 'dec'), counts)]
        cfg = ModelConfig.from_dict(manifest['model_config'])
        norm = normalizer_from_dict(manifest['normalizer'])
    except (OSError, ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile) as exc:
        raise CorruptArtifact(f'cannot read model twin {path}: {exc}') from exc
    if manifest.get('kind') != KIND or manifest.get('format_version') != FORMAT_VERSION:
        raise CorruptArtifact(f'{path} is not a sik_ros model twin of format {FORMAT_VERSION}')
    for part in layers:
        for w, b in part:
            if w.dtype != np.float32 or w.ndim != 2 or b.shape != (w.shape[1],):
                raise CorruptArtifact(f'model twin {path}: a layer of shape {w.shape} with a '
                                      f'bias of {b.shape}')
    return NumpySIK(cfg, *layers), cfg, norm, manifest
