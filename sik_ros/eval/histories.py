"""Training histories read from checkpoints: the latent-size study and the training curves.

Experiment 4's latent-size study is a training study (one model per index size, trained
beforehand, e.g. with ``scripts/latent_study.sh``); its results, like the training curves of the
evaluated bundle, come from the checkpoints' stored histories.
"""

from dataclasses import dataclass, field
from pathlib import Path
import re
from typing import Dict, List, Optional, Union

from sik_ros.artifacts import read_json
from sik_ros.learning.checkpoints import load_checkpoint
from sik_ros.learning.provenance import trained_summary
from sik_ros.solver import SelectiveIK


@dataclass
class TrainedModel:
    """A trained model's checkpoint summary.

    Attributes:
        history: the training records (``step``, ``loss``, ``val_dist_mean_m`` [m], ...).
        step: training steps taken.
        elapsed_s: training time [s].
        config: the model configuration (``latent_dim``, ``encoder``, ``decoder``, ...).
        train_config: the training settings (``batch_size``, ``sampler``, ``init``, ...).
        trained: where, how long and on how many samples it was trained
            (:func:`~sik_ros.learning.provenance.trained_summary`).
    """

    history: List[Dict]
    step: int
    elapsed_s: float
    config: Dict
    train_config: Dict = field(default_factory=dict)
    trained: Dict = field(default_factory=dict)


@dataclass
class LatentRun:
    """One checkpoint of the latent-size study.

    Attributes:
        latent_dim: the posture index size.
        path: the checkpoint file.
        step: training steps taken.
        final_loss: the loss of the last record (None without records).
        val_dist_mean_m: the validation distance error of the last record [m] (or None).
        history: the training records.
    """

    latent_dim: int
    path: str
    step: int
    final_loss: Optional[float]
    val_dist_mean_m: Optional[float]
    history: List[Dict]


def bundle_histories(ik: SelectiveIK) -> Dict[str, TrainedModel]:
    """The training summaries of a bundle's models, by goal kind (none without a manifest)."""
    out: Dict[str, TrainedModel] = {}
    if ik.bundle is None or not (Path(ik.bundle) / 'bundle.json').is_file():
        return out
    manifest = read_json(Path(ik.bundle) / 'bundle.json', f'bundle {ik.bundle}')
    for goal, files in manifest['models'].items():
        ckpt = load_checkpoint(Path(ik.bundle) / files['model'])
        out[goal] = TrainedModel(ckpt.get('history', []), int(ckpt.get('step', 0)),
                                 float(ckpt.get('elapsed_s', 0.0)), ckpt['model_config'],
                                 dict(ckpt.get('train_config', {})), trained_summary(ckpt))
    return out


def latent_study(directory: Optional[Union[str, Path]]) -> Optional[List[LatentRun]]:
    """The latent-size study from checkpoints ``latent_<d>.pt`` (None without a directory).

    Returns:
        one :class:`LatentRun` per checkpoint, sorted by size.
    """
    if directory is None:
        return None
    rows = []
    for path in sorted(Path(directory).glob('latent_*.pt')):
        if not re.fullmatch(r'latent_\d+\.pt', path.name):
            continue
        ckpt = load_checkpoint(path)
        hist = list(ckpt.get('history', []))
        last = hist[-1] if hist else {}
        rows.append(LatentRun(int(ckpt['model_config']['latent_dim']), str(path),
                              int(ckpt.get('step', 0)), last.get('loss'),
                              last.get('val_dist_mean_m'), hist))
    return sorted(rows, key=lambda r: r.latent_dim)
