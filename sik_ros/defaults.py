"""Defaults of the data, model, table and build settings, in one light module.

The command-line tools read their defaults here to build their ``--help`` without loading
torch or Pinocchio; the library modules that use them (:mod:`~sik_ros.tables.dataset`,
:mod:`~sik_ros.learning.models`, :mod:`~sik_ros.tables.index_table`,
:mod:`~sik_ros.tables.seed_table`, :mod:`~sik_ros.bundles.build`) import them from here.
"""

from dataclasses import dataclass
import math

from sik_ros.errors import InvalidArgument

#: Model kinds (``sik-train --model``) and goal kinds.
MODEL_KINDS = ('sik', 'psik', 'fcn', 'anfis')
GOAL_KINDS = ('position', 'pose')
#: Posture index sizes per goal kind of the bundled Panda models.
DEFAULT_LATENT = {'position': 4, 'pose': 1}

#: Layer-width presets: (encoder hidden widths, decoder hidden widths).
PRESETS = {
    'paper': ((2048, 2048, 1024, 512), (512, 1024, 1024, 512)),
    'default': ((256, 256, 256), (512, 512, 512, 512)),
    'small': ((128, 128), (256, 256, 256)),
    'tiny': ((32, 32), (64, 64)),
}

#: Samples per training step of ``sik-build`` on a CPU and on a GPU (the paper's batch).
BUILD_BATCH = {'cpu': 2048, 'cuda': 65536}
#: Default row budget of a collection (``sik-collect --max-rows``).
MAX_ROWS = 20_000_000
#: Configurations a seed table keeps by default (6 MB for 6 joints).
SEED_TABLE_ROWS = 500_000
#: Configurations the seed table of a 7-joint arm keeps: the family search's starts, far apart
#: rather than near the goal (0.4 MB; docs/design.md, "Measured choices").
SEARCH_SEED_TABLE_ROWS = 30_000


@dataclass(frozen=True)
class TableConfig:
    """How a posture-index table is built.

    Attributes:
        cell: edge of the position cells [m].
        dedup: indices closer than this (per element, in index units) count as one.
        max_per_cell: most indices kept per cell (a far-apart subset).
        max_tip_error: mark the indices whose decoded tip comes within this of the goal at
            their cell's centre and one cell away along each axis [m] (and each cell's best):
            the look-up by position gives only those; 0 marks none. Position-goal models only.
    """

    cell: float = 0.05
    dedup: float = 0.05
    max_per_cell: int = 24
    max_tip_error: float = 0.0

    def __post_init__(self):
        """Validate the fields."""
        if not (self.cell > 0 and self.dedup > 0 and self.max_per_cell >= 1
                and math.isfinite(self.max_tip_error) and self.max_tip_error >= 0):
            raise InvalidArgument(f'invalid table config {self}')


@dataclass(frozen=True)
class BuildConfig:
    """What a build does; a rerun must ask for the same (``time`` may change).

    Attributes:
        time: total wall-clock budget [s]; training gets what the other stages leave.
        sampler: ``uniform`` or ``grid`` (the finest interval whose grid fits ``rows``).
        rows: uniform samples, or the grid's row budget.
        preset: layer widths (:data:`PRESETS`).
        device: ``cpu`` or ``cuda``.
        batch_size: samples per training step (:data:`BUILD_BATCH` by device).
        check_targets: targets per goal kind of the self-check.
        seed: seed of the sampler, the training and the self-check.
        cores: training processes at once: 2, the position and the pose model side by side;
            1, one after the other (a build in the background of a node, on one core).
    """

    time: float = 1800.0
    sampler: str = 'uniform'
    rows: int = 3_000_000
    preset: str = 'default'
    device: str = 'cpu'
    batch_size: int = 2048
    check_targets: int = 200
    seed: int = 0
    cores: int = 2

    def __post_init__(self):
        """Validate the fields."""
        if not (math.isfinite(self.time) and self.time > 0):
            raise InvalidArgument(f'--time must be a positive number of seconds; got {self.time}')
        if self.sampler not in ('uniform', 'grid'):
            raise InvalidArgument(f'--sampler must be uniform or grid; got {self.sampler!r}')
        if not 1000 <= self.rows <= MAX_ROWS:
            raise InvalidArgument(f'--rows must be in 1,000..{MAX_ROWS:,}; got {self.rows:,}')
        if self.preset not in PRESETS:
            raise InvalidArgument(f'--preset must be one of {sorted(PRESETS)}')
        if self.device not in ('cpu', 'cuda'):
            raise InvalidArgument(f'--device must be cpu or cuda; got {self.device!r}')
        if self.cores not in (1, 2):
            raise InvalidArgument(f'--cores must be 1 or 2; got {self.cores!r}')
