"""Where, how long and on how many samples a model was trained.

Every checkpoint written by the trainer carries ``trained``: one segment per call of the
training loop (a run and each of its resumptions), each with the device's name, the
processes, the steps, the samples and the seconds, and the totals, plus the same record of the
model it started from (``--init``), if any. :func:`trained_summary` reads it back, or derives
what it can (steps, seconds, ``steps x batch``) from a checkpoint written before it was
recorded; ``bundle.json`` and ``sik-eval`` show it. Light: torch is loaded only to name a
device.
"""

from datetime import datetime, timezone
import os
from pathlib import Path
import platform
from typing import Any, Dict, List, Mapping, Optional


def device_name(device: Any) -> str:
    """A device's name as a record keeps it: the GPU's model, or the CPU's and its threads."""
    import torch
    device = torch.device(device)
    if device.type == 'cuda':
        return torch.cuda.get_device_name(device)
    return f'cpu: {cpu_model()}, {torch.get_num_threads()} threads'


def cpu_model() -> str:
    """The processor's model name (``/proc/cpuinfo``), else the machine type."""
    try:
        for line in Path('/proc/cpuinfo').read_text().splitlines():
            if line.startswith('model name'):
                return line.split(':', 1)[1].strip()
    except OSError:
        pass
    return platform.machine() or platform.processor() or f'{os.cpu_count()} cores'


class Provenance:
    """A model's training record, as it grows during a run (:meth:`record` for checkpoints)."""

    def __init__(self, segments: Optional[List[Dict]] = None, init: Optional[Dict] = None):
        self.segments = [dict(s) for s in segments or []]
        self.init = init

    @classmethod
    def from_checkpoint(cls, ckpt: Mapping) -> 'Provenance':
        """The record of a checkpoint being resumed (one derived segment if it has none)."""
        rec = ckpt.get('trained')
        if isinstance(rec, Mapping) and isinstance(rec.get('segments'), list):
            return cls(rec['segments'], rec.get('init'))
        summary = trained_summary(ckpt)
        return cls([{'device': 'not recorded', 'processes': 1, 'first_step': 0,
                     'steps': summary['steps'], 'samples': summary['samples'],
                     'seconds': summary['seconds'], 'date': ''}])

    def start(self, device: str, processes: int, step: int) -> None:
        """A new segment: the training loop starts (or resumes) at ``step`` on ``device``."""
        self.segments.append({'device': device, 'processes': int(processes),
                              'first_step': int(step), 'steps': 0, 'samples': 0,
                              'seconds': 0.0, 'date': datetime.now(timezone.utc)
                              .strftime('%Y-%m-%dT%H:%M:%SZ')})

    def stepped(self, step: int, samples: int, seconds: float) -> None:
        """A step done: the segment's steps, ``samples`` more, ``seconds`` since it started."""
        seg = self.segments[-1]
        seg['steps'] = int(step) - seg['first_step']
        seg['samples'] += int(samples)
        seg['seconds'] = round(float(seconds), 2)

    def started_from(self, source: str, ckpt: Mapping) -> None:
        """The run starts from another model's weights (``--init``): keep that one's record."""
        self.init = {'file': Path(source).name, **trained_summary(ckpt)}

    def record(self, step: int) -> Dict:
        """The record a checkpoint stores: segments, totals, devices and the start."""
        segs = [s for s in self.segments if s['steps'] > 0 or s is self.segments[-1]]
        return {'segments': segs, 'steps': int(step),
                'samples': int(sum(s['samples'] for s in segs)),
                'seconds': round(sum(s['seconds'] for s in segs), 1),
                'devices': sorted({s['device'] for s in segs if s['steps'] > 0}),
                'init': self.init}


def trained_summary(ckpt: Mapping) -> Dict:
    """A checkpoint's training in short: steps, samples, seconds, devices, and its start.

    ``recorded`` is False for a checkpoint without a record: its samples are then its steps
    times its batch (one process), its device ``not recorded``. ``total_samples`` and
    ``total_seconds`` add those of the models it started from.
    """
    rec = ckpt.get('trained')
    if isinstance(rec, Mapping) and 'samples' in rec:
        out = {'recorded': True, 'steps': int(rec.get('steps', 0)),
               'samples': int(rec['samples']), 'seconds': float(rec.get('seconds', 0.0)),
               'devices': list(rec.get('devices', [])), 'init': rec.get('init')}
    else:
        tc = ckpt.get('train_config') or {}
        kind = (ckpt.get('model_config') or {}).get('kind')
        batch = tc.get('pso_batch' if kind == 'anfis' else 'batch_size', 0)
        step = int(ckpt.get('step', 0))
        out = {'recorded': False, 'steps': step, 'samples': step * int(batch or 0),
               'seconds': round(float(ckpt.get('elapsed_s', 0.0)), 1),
               'devices': ['not recorded'], 'init': None}
    init = out['init'] or {}
    out['total_samples'] = out['samples'] + int(init.get('total_samples', 0))
    out['total_seconds'] = round(out['seconds'] + float(init.get('total_seconds', 0.0)), 1)
    return out


def describe(summary: Mapping) -> str:
    """One line of a training summary: samples and time, where, and from what it started."""
    where = ', '.join(summary.get('devices') or []) or 'not recorded'
    line = (f'{summary["samples"]:,} samples in {summary["seconds"] / 60:.1f} min on {where}')
    init = summary.get('init')
    if init:
        line += (f'; started from {init.get("file", "another model")} '
                 f'({init["total_samples"]:,} samples, {init["total_seconds"] / 60:.1f} min '
                 f'before)')
    return line
