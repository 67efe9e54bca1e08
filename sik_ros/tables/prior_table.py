"""A table of posture indices for a PSIK model that comes without one: draws from its prior."""

from typing import Tuple

import numpy as np

from sik_ros.errors import InvalidArgument


class PriorTable:
    """A :class:`PostureTable` for a PSIK model without a table: draws from its prior.

    PSIK's posture indices are trained towards N(0, I), so a fixed set of draws (the same for
    every target) stands in for the table's indices near the target. It knows nothing of the
    workspace: every goal counts as near the data.
    """

    orientations = None
    postures = None

    def __init__(self, latent_dim: int, count: int = 48, seed: int = 0):
        rng = np.random.default_rng(seed)
        self.indices = rng.standard_normal((count, latent_dim)).astype(np.float32)
        self.latent_dim = latent_dim

    @property
    def index_bounds(self) -> Tuple[np.ndarray, np.ndarray]:
        """Element-wise (min, max) of the draws."""
        return self.indices.min(axis=0), self.indices.max(axis=0)

    def rows_near(self, position: np.ndarray, k_cells: int) -> np.ndarray:
        """Every draw, whatever the position."""
        return np.arange(len(self.indices))

    def pool_cells(self, k_cells: int) -> int:
        """``k_cells``: the draws have no cells."""
        return k_cells

    def distance_to_data(self, position: np.ndarray) -> float:
        """0: the prior covers every goal."""
        return 0.0

    def within(self, position: np.ndarray, distance: float) -> bool:
        """True: the prior covers every goal."""
        return True

    def oriented_rows(self, position: np.ndarray, quaternion: np.ndarray, count: int,
                      k_cells: int = 8) -> np.ndarray:
        """Refused: prior draws carry no orientation.

        Raises:
            InvalidArgument: always.
        """
        raise InvalidArgument('a prior table keeps no orientations')
