"""What a model is, without torch: its architecture, its units, its goal vectors.

:class:`ModelConfig` (saved inside every checkpoint), :class:`Normalizer` (joints and goals to
and from the networks' units; its tensor methods import torch when called), the goal vectors
of :func:`make_goal`. Inference that runs without torch (a bundle's NumPy twins,
:mod:`sik_ros.learning.twins`) reads these; :mod:`sik_ros.learning.models` re-exports them.
"""

from dataclasses import dataclass, field
from typing import Dict, Optional, Tuple, TYPE_CHECKING

import numpy as np

from sik_ros.defaults import GOAL_KINDS, MODEL_KINDS, PRESETS
from sik_ros.errors import InvalidArgument

if TYPE_CHECKING:  # the tensor methods' types; torch is imported when they are called
    import torch


@dataclass(frozen=True)
class ModelConfig:
    """Architecture of a model; saved inside every checkpoint.

    Attributes:
        kind: ``sik``, ``psik``, ``fcn`` or ``anfis``.
        goal: ``position`` (3-d goal) or ``pose`` (position + orientation, 9-d goal).
        dof: number of joints.
        latent_dim: size of the posture index (SIK/PSIK).
        encoder: hidden widths of the encoder.
        decoder: hidden widths of the decoder (and of the FCN).
        anfis_mfs: membership functions per input (ANFIS).
        branches: the branch code beside the learned index (SIK): per bit ``(joint, scale,
            offset)``, the bit being the sign of ``sin(x[joint] * scale + offset)`` for the
            normalised joint ``x`` (that is, of ``sin(q - s)`` with ``s`` the angle at which
            the joint's neighbouring axes line up: the shoulder and wrist flips of an arm,
            :func:`branch_bits`). The posture index is the learned part followed by the bits.
    """

    kind: str = 'sik'
    goal: str = 'position'
    dof: int = 7
    latent_dim: int = 4
    encoder: Tuple[int, ...] = PRESETS['default'][0]
    decoder: Tuple[int, ...] = PRESETS['default'][1]
    anfis_mfs: int = 2
    branches: Tuple[Tuple[int, float, float], ...] = ()

    def __post_init__(self):
        """Validate the fields."""
        if self.kind not in MODEL_KINDS:
            raise InvalidArgument(f'model kind must be one of {MODEL_KINDS}; got {self.kind!r}')
        if self.goal not in GOAL_KINDS:
            raise InvalidArgument(f'goal must be one of {GOAL_KINDS}; got {self.goal!r}')
        if not 1 <= self.latent_dim <= max(7, self.dof):
            raise InvalidArgument(f'latent dimension must be 1 to {max(7, self.dof)}; got '
                                  f'{self.latent_dim}')
        if self.dof < 1:
            raise InvalidArgument(f'dof must be positive; got {self.dof}')
        for bit in self.branches:
            if len(bit) != 3 or not 0 <= int(bit[0]) < self.dof:
                raise InvalidArgument(f'a branch bit is (joint, scale, offset) with a joint '
                                      f'below {self.dof}; got {bit!r}')
        if self.branches and self.kind != 'sik':
            raise InvalidArgument(f'a branch code needs a sik model; got {self.kind!r}')

    @property
    def index_dim(self) -> int:
        """Size of the posture index: the learned part and the branch bits."""
        return self.latent_dim + len(self.branches)

    @property
    def goal_dim(self) -> int:
        """Size of the goal vector."""
        return 3 if self.goal == 'position' else 9

    @classmethod
    def from_dict(cls, d: Dict) -> 'ModelConfig':
        """Rebuild from :func:`dataclasses.asdict` output."""
        d = dict(d)
        d['encoder'] = tuple(d['encoder'])
        d['decoder'] = tuple(d['decoder'])
        d['branches'] = tuple((int(j), float(a), float(b)) for j, a, b in d.get('branches', ()))
        return cls(**d)


@dataclass(frozen=True)
class Normalizer:
    """Maps joints and goals to and from the networks' normalised units."""

    lower: Tuple[float, ...]
    upper: Tuple[float, ...]
    position_center: Tuple[float, ...] = (0.0, 0.0, 0.0)
    position_scale: float = 1.0
    extra: Dict = field(default_factory=dict)

    def q_to_net(self, q: 'torch.Tensor') -> 'torch.Tensor':
        """Joint positions [rad] to [-1, 1]."""
        lo, hi = self._limits(q)
        return (q - (lo + hi) / 2) / ((hi - lo) / 2)

    def q_from_net(self, x: 'torch.Tensor') -> 'torch.Tensor':
        """Normalised joints back to [rad]."""
        lo, hi = self._limits(x)
        return x * ((hi - lo) / 2) + (lo + hi) / 2

    def goal_to_net(self, goal: 'torch.Tensor') -> 'torch.Tensor':
        """A goal (position [m], optionally followed by 6 rotation entries) to network units."""
        import torch
        c = torch.as_tensor(self.position_center, dtype=goal.dtype, device=goal.device)
        pos = (goal[:, :3] - c) / self.position_scale
        return torch.cat([pos, goal[:, 3:]], dim=1)

    def _limits(self, like: 'torch.Tensor'):
        import torch
        lo = torch.as_tensor(self.lower, dtype=like.dtype, device=like.device)
        hi = torch.as_tensor(self.upper, dtype=like.dtype, device=like.device)
        return lo, hi


def rotation_goal(rot: np.ndarray) -> np.ndarray:
    """The 6-d orientation representation: first two columns of (N, 3, 3) rotations, (N, 6)."""
    return np.concatenate([rot[:, :, 0], rot[:, :, 1]], axis=1)


def make_goal(goal_kind: str, position: np.ndarray, rot: Optional[np.ndarray]) -> np.ndarray:
    """Goal vectors (N, 3) or (N, 9) from positions [m] and rotation matrices."""
    if goal_kind == 'position':
        return np.asarray(position, dtype=float)
    return np.concatenate([position, rotation_goal(rot)], axis=1)


def normalizer_from_dict(d: Dict) -> Normalizer:
    """A :class:`Normalizer` from its checkpoint dict."""
    return Normalizer(tuple(d['lower']), tuple(d['upper']), tuple(d['position_center']),
                      float(d['position_scale']), dict(d.get('extra', {})))
