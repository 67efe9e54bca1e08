"""Candidates: the rows that travel together through the solver (joints, index, errors)."""

from dataclasses import dataclass
from typing import Union

import numpy as np


@dataclass(frozen=True)
class Candidates:
    """A batch of M candidate solutions; row i of every array belongs to candidate i.

    Attributes:
        q: joint positions (M, n) [rad].
        z: posture indices (M, latent); NaN rows are encoded once ranked.
        perr: position errors (M,) [m].
        oerr: orientation errors (M,) [rad] (zeros for position goals).
        exact: whether each meets the tolerances (M,) bool.
    """

    q: np.ndarray
    z: np.ndarray
    perr: np.ndarray
    oerr: np.ndarray
    exact: np.ndarray

    def __len__(self) -> int:
        """Number of candidates."""
        return len(self.q)

    def take(self, rows: Union[np.ndarray, slice]) -> 'Candidates':
        """The candidates selected by a boolean mask, an index array or a slice."""
        return Candidates(self.q[rows], self.z[rows], self.perr[rows], self.oerr[rows],
                          self.exact[rows])

    @staticmethod
    def concat(*parts: 'Candidates') -> 'Candidates':
        """The candidates of several batches, in order."""
        return Candidates(*(np.concatenate([getattr(p, name) for p in parts])
                            for name in ('q', 'z', 'perr', 'oerr', 'exact')))
