"""Defaults of the data, table and seed-table builders, in one light module.

The command-line tools read their defaults here to build their ``--help`` without loading
NumPy's heavier neighbours, torch or Pinocchio; the library modules that use them
(:mod:`~sik_ros.dataset`, :mod:`~sik_ros.index_table`, :mod:`~sik_ros.seed_table`) import them
from here.
"""

from dataclasses import dataclass

from sik_ros.errors import InvalidArgument

#: Default row budget of a collection (``sik-collect --max-rows``).
MAX_ROWS = 20_000_000
#: Configurations a seed table keeps by default (6 MB for 6 joints).
SEED_TABLE_ROWS = 500_000


@dataclass(frozen=True)
class TableConfig:
    """How a posture-index table is built.

    Attributes:
        cell: edge of the position cells [m].
        dedup: indices closer than this (per element, in index units) count as one.
        max_per_cell: most indices kept per cell (a far-apart subset).
    """

    cell: float = 0.05
    dedup: float = 0.05
    max_per_cell: int = 24

    def __post_init__(self):
        """Validate the fields."""
        if not (self.cell > 0 and self.dedup > 0 and self.max_per_cell >= 1):
            raise InvalidArgument(f'invalid table config {self}')
