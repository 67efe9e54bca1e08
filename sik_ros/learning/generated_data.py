"""Training rows generated where the model trains: the Algorithm 1 grid or uniform samples.

``sik-train --chain`` trains from a chain file (:mod:`sik_ros.kinematics.chain_file`) on a
machine without Pinocchio or a dataset on disk: the rows are made on the training device
itself, the joint values of the paper's Algorithm 1 grid (the same values and row order as
``sik-collect --sampler grid``) or uniform within the limits, and their tips by the torch FK
(:class:`~sik_ros.learning.models.TorchChain`) in float64. They stay on the device as float32
tensors, as :class:`~sik_ros.learning.training_data.TrainData` holds a dataset's rows.
"""

from typing import Any, Dict, Optional

import numpy as np
import torch

from sik_ros.errors import InvalidArgument
from sik_ros.learning.models import TorchChain
from sik_ros.tables.dataset import grid_count, grid_values

#: Row generators of :class:`GeneratedData`.
GENERATED = ('grid', 'uniform')
#: Most rows generated (the paper's 30-degree Panda grid has 6,967,296): 25 float32 a row.
MAX_GENERATED = 100_000_000
#: Rows whose FK is computed at a time.
CHUNK = 1 << 20


class GeneratedData:
    """Rows of joint values and their tips, generated on a device.

    Attributes:
        q: joint values (N, n) [rad], float32.
        position: tip positions (N, 3) [m], float32.
        rot6: the first two columns of the tip rotations (N, 6), float32.
        manifest: what a checkpoint records of the data (``kind`` ``generated``, the sampler,
            its parameters, the row count and the robot).
        workspace: a float64 sample of the tip positions (every ``N // 200,000``-th row, as
            :func:`~sik_ros.learning.training_data.default_normalizer` takes of a dataset).
    """

    def __init__(self, arm: Any, sampler: str = 'grid', interval_deg: float = 30.0,
                 samples: int = 0, seed: int = 0, device: str = 'cpu'):
        """Generate the rows.

        Args:
            arm: a robot or :class:`~sik_ros.kinematics.chain_file.ChainArm` (its ``chain``,
                ``lower``, ``upper``, ``periodic`` and ``manifest()``).
            sampler: ``grid`` (Algorithm 1) or ``uniform``.
            interval_deg: the grid's step [deg].
            samples: rows of the uniform sampler.
            seed: seed of the uniform sampler.
            device: where the rows are made and kept (``cpu`` or ``cuda``).

        Raises:
            InvalidArgument: an unknown sampler, a bad interval or sample count, or more rows
                than :data:`MAX_GENERATED`.
        """
        if sampler not in GENERATED:
            raise InvalidArgument(f'generated data is grid or uniform; got {sampler!r}')
        lower, upper = np.asarray(arm.lower, float), np.asarray(arm.upper, float)
        dev = torch.device(device)
        if sampler == 'grid':
            count = grid_count(lower, upper, interval_deg, arm.periodic)
            params: Dict = {'interval_deg': float(interval_deg)}
        else:
            if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
                raise InvalidArgument(f'uniform samples must be at least 1; got {samples!r}')
            count, params = samples, {'samples': samples, 'seed': seed}
        if count > MAX_GENERATED:
            raise InvalidArgument(f'{sampler} data of {count:,} rows is above {MAX_GENERATED:,}; '
                                  f'take a coarser --interval or fewer --samples')
        if sampler == 'grid':
            q = grid_configurations(lower, upper, interval_deg, arm.periodic, dev)
        else:
            gen = torch.Generator(device=dev).manual_seed(seed)
            lo = torch.as_tensor(lower, dtype=torch.float64, device=dev)
            hi = torch.as_tensor(upper, dtype=torch.float64, device=dev)
            q = lo + (hi - lo) * torch.rand(count, len(lower), generator=gen, device=dev,
                                            dtype=torch.float64)
        self.q, self.position, self.rot6, self.workspace = _forward(arm.chain, q)
        self.manifest = {'kind': 'generated', 'sampler': sampler, 'params': params,
                         'count': int(count), 'robot': arm.manifest()}

    def __len__(self) -> int:
        """Number of rows."""
        return len(self.q)

    def summary(self) -> Dict:
        """What a checkpoint records of the data (as ``dataset_summary`` does of a dataset)."""
        m = self.manifest
        return {'kind': 'generated', 'sampler': m['sampler'], 'params': dict(m['params']),
                'count': m['count'], 'robot': m['robot']['robot'],
                'urdf_sha256': m['robot'].get('urdf_sha256')}


def grid_configurations(lower: np.ndarray, upper: np.ndarray, interval_deg: float,
                        periodic: Optional[np.ndarray], device: torch.device) -> torch.Tensor:
    """The Algorithm 1 grid's configurations (N, n) [rad], float64, first joint slowest."""
    values = [torch.as_tensor(v, dtype=torch.float64, device=device)
              for v in grid_values(lower, upper, interval_deg, periodic)]
    return torch.cartesian_prod(*values).reshape(-1, len(values))


def _forward(chain: Any, q: torch.Tensor):
    """float32 joints, positions and rot6 of float64 joints, and a float64 workspace sample."""
    fk = TorchChain(chain, dtype=torch.float64).to(q.device)
    n = len(q)
    q32 = torch.empty(q.shape, dtype=torch.float32, device=q.device)
    pos32 = torch.empty((n, 3), dtype=torch.float32, device=q.device)
    rot32 = torch.empty((n, 6), dtype=torch.float32, device=q.device)
    stride = max(1, n // 200_000)
    sample = []
    with torch.no_grad():
        for s in range(0, n, CHUNK):
            p, r = fk(q[s:s + CHUNK])
            q32[s:s + CHUNK] = q[s:s + CHUNK]
            pos32[s:s + CHUNK] = p
            rot32[s:s + CHUNK] = torch.cat([r[:, :, 0], r[:, :, 1]], 1)
            first = (-s) % stride  # the rows of this chunk on the global stride
            sample.append(p[first::stride].cpu().numpy())
    workspace = np.concatenate(sample) if sample else np.zeros((0, 3))
    return q32, pos32, rot32, workspace
