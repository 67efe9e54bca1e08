"""A revolute serial chain's constant geometry and its batched forward kinematics.

Forward kinematics is vectorised over configurations and written once for NumPy and PyTorch
(:func:`chain_forward`), so the training loss and the solver share it.
"""

from dataclasses import dataclass
from typing import Any, Optional, Tuple

import numpy as np


@dataclass(frozen=True)
class SerialChain:
    """Constant geometry of a revolute serial chain [m, rad].

    Attributes:
        joint_rotations: (n, 3, 3) rotation of each joint frame in its parent joint frame; the
            frames are turned so that every joint rotates about its own z axis.
        joint_translations: (n, 3) translation of each joint frame in its parent [m].
        axes: (n, 3) the joints' axes as the URDF gives them (for reference).
        base_rotation: (3, 3) rotation of the world in the base frame.
        base_translation: (3,) translation of the world in the base frame [m].
        tip_rotation: (3, 3) rotation of the tip in the last joint frame.
        tip_translation: (3,) translation of the tip in the last joint frame [m].
    """

    joint_rotations: np.ndarray
    joint_translations: np.ndarray
    axes: np.ndarray
    base_rotation: np.ndarray
    base_translation: np.ndarray
    tip_rotation: np.ndarray
    tip_translation: np.ndarray

    @property
    def dof(self) -> int:
        """Number of joints."""
        return len(self.axes)


def chain_forward(chain: Any, q: Any, xp: Any = np, frames: bool = False, first: int = 0,
                  start: Optional[Tuple[Any, Any]] = None, tip: bool = True):
    """Forward kinematics of a serial chain for a batch of configurations.

    Every joint of a :class:`SerialChain` turns about its own z axis (the extraction rotates
    joint frames so that this holds), so a joint's rotation only mixes two columns. Works for
    NumPy arrays (``xp=numpy``) and torch tensors (``xp=torch``, with the chain's arrays as
    tensors), so the training loss and the solver share it.

    Args:
        chain: a :class:`SerialChain` (or an object with the same array attributes).
        q: (N, n) joint positions [rad].
        xp: the array module, ``numpy`` or ``torch``.
        frames: also return every joint's world position and axis.
        first: index of the joint that ``q[:, 0]`` drives (to continue a partial chain).
        start: ``(positions, rotations)`` of joint ``first - 1``'s frame; the base if None.
        tip: apply the tip offset; else return the frame of the last joint computed.

    Returns:
        ``(p, R)``: tip positions (N, 3) [m] and rotations (N, 3, 3) in the base frame; with
        ``frames=True`` also joint origins (N, n, 3) and world axes (N, n, 3).
    """
    c = xp.cos(q)
    s = xp.sin(q)
    if start is None:
        rot = chain.base_rotation
        pos = chain.base_translation + 0 * q[:, :1]
    else:
        pos, rot = start
    origins, axes_world = [], []
    for col in range(q.shape[1]):
        i = first + col
        pos = pos + rot @ chain.joint_translations[i]
        a = rot @ chain.joint_rotations[i]
        ci, si = c[:, col, None], s[:, col, None]
        a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
        rot = xp.stack([ci * a0 + si * a1, ci * a1 - si * a0, a2 + 0 * ci], -1)
        if frames:
            origins.append(pos)
            axes_world.append(a2 + 0 * ci)
    if tip:
        pos, rot = pos + rot @ chain.tip_translation, rot @ chain.tip_rotation
    if frames:
        return pos, rot, xp.stack(origins, 1), xp.stack(axes_world, 1)
    return pos, rot
