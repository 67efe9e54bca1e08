"""A bundle's parts with no learned model: the arm's collected configurations as the table.

Algorithm 1 (a sweep of the joint space, tip poses by forward kinematics) gives, for every
workspace cell, configurations whose tips lie in it. The solver refines from postures, not from
networks: a table whose "posture index" is the configuration itself (decoding is the identity,
encoding too) gives it starts as good as a learned table's (docs/benchmarks.md, "First answers").
:func:`sweep_models` builds such a table per goal kind in seconds, from uniform samples of the
joint space sized to a time budget, plus the seed table an arm of seven joints or fewer uses
for pose goals. What needs the network (raw answers, ``refine=False``) is refused by the solver
until the learned model arrives (:class:`~sik_ros.errors.ModelNotReady`).
"""

import math
import time
from typing import Dict, Optional

import numpy as np

from sik_ros.artifacts import FORMAT_VERSION
from sik_ros.bundles.bundle import GoalModel, GOALS
from sik_ros.defaults import TableConfig
from sik_ros.errors import InvalidArgument
from sik_ros.kinematics.robot import Robot
from sik_ros.tables.dataset import Dataset
from sik_ros.tables.index_table import IndexTable
from sik_ros.tables.seed_table import default_rows, SeedTable

#: The table of configurations: 5 cm cells (as a learned table's), configurations closer than
#: 0.25 rad in every joint counted once, at most 24 far apart per cell.
SWEEP_TABLE = TableConfig(cell=0.05, dedup=0.25, max_per_cell=24)
#: Configurations swept by default, and the least a budget may cut them to.
SWEEP_ROWS = 400_000
MIN_ROWS = 20_000
#: Seed-table rows (arms of six joints or fewer), at most.
SWEEP_SEED_ROWS = 300_000


def sweep_rows(robot: Robot, seconds: float, probe: int = 4096) -> int:
    """Configurations whose sweep and table fit ``seconds`` [s] here (measured on a probe).

    The table costs about three times the forward kinematics per row (its sort and far-apart
    subsets): the rows are sized to a quarter of the budget's FK time.
    """
    q = np.random.default_rng(0).uniform(robot.lower, robot.upper, (probe, robot.dof))
    t0 = time.perf_counter()
    robot.fk_batch(q)
    per_row = max((time.perf_counter() - t0) / probe, 1e-8)
    return int(np.clip(0.25 * seconds / per_row, MIN_ROWS, SWEEP_ROWS))


def sweep_dataset(robot: Robot, rows: int, seed: int = 0) -> Dataset:
    """``rows`` configurations uniform within the limits and their tip poses, in memory."""
    if isinstance(rows, bool) or not isinstance(rows, (int, np.integer)) or rows < 1:
        raise InvalidArgument(f'rows must be an integer >= 1; got {rows!r}')
    q = np.random.default_rng(seed).uniform(robot.lower, robot.upper, (int(rows), robot.dof))
    position, quaternion = robot.fk_batch(q)
    manifest = {'kind': 'dataset', 'count': int(rows), 'robot': robot.manifest(),
                'params': {'sampler': 'uniform', 'samples': int(rows), 'seed': int(seed)}}
    return Dataset(None, manifest, q, np.asarray(position), np.asarray(quaternion))


def configuration_table(robot: Robot, ds: Dataset,
                        cfg: TableConfig = SWEEP_TABLE) -> IndexTable:
    """An index table whose indices and postures are the dataset's configurations [rad].

    Per cell, distinct configurations far apart in joint space, each with its tip orientation.
    """
    manifest = {'robot': robot.manifest(), 'goal': 'configuration', 'model': None,
                'dataset': {'count': len(ds), 'params': ds.manifest.get('params')},
                'format_version': FORMAT_VERSION}
    table = IndexTable.build(ds.q, ds.position, cfg, manifest, ds.quaternion)
    return table.with_postures(table.indices, robot.lower, robot.upper)


def sweep_models(robot: Robot, seconds: float = 3.0, rows: Optional[int] = None,
                 seed: int = 0) -> Dict[str, GoalModel]:
    """Both goal kinds' parts for the solver, with no network: one table of configurations.

    Args:
        robot: the arm.
        seconds: the time the sweep and its tables may take here [s] (sizes ``rows``).
        rows: configurations to sweep (None: sized to ``seconds``).
        seed: seed of the sweep.

    Returns:
        a :class:`GoalModel` per goal kind (``model`` None), sharing one table; the pose goal
        of an arm of seven joints or fewer also gets a seed table
        (:func:`~sik_ros.tables.seed_table.default_rows`).
    """
    if not (isinstance(seconds, (int, float)) and math.isfinite(seconds) and seconds > 0):
        raise InvalidArgument(f'seconds must be a positive number; got {seconds!r}')
    rows = sweep_rows(robot, seconds) if rows is None else rows
    ds = sweep_dataset(robot, rows, seed)
    table = configuration_table(robot, ds)
    most = default_rows(robot)
    seeds = SeedTable.build(robot, ds, min(len(ds), SWEEP_SEED_ROWS, most), seed) \
        if most else None
    return {goal: GoalModel(None, None, None, table, seeds if goal == 'pose' else None)
            for goal in GOALS}
