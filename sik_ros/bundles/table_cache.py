"""An arm's table of configurations kept in its cache entry: a restart loads what a start built.

The table of configurations (:mod:`~sik_ros.bundles.sweep_models`) costs seconds of sweep,
forward kinematics, KD-trees and distance grids; its arrays load in a fraction of that. At its
first build the entry gets ``table/`` (:class:`~sik_ros.bundles.cache.ArmEntry`):

- ``table.json``: what it is (``kind``, format), the chain's cache key, the ``sweep_time`` it
  was sized to, the robot's manifest and the two tables' manifests;
- ``configurations.npz``: the table of configurations (its cells' centres and offsets, the
  configurations, their tip orientations) and its reach grid's distances;
- ``seeds.npz`` (arms of seven joints or fewer): the seed table's rows as 16-bit joint codes,
  in its KD-tree's leaf order, with the built trees and the rows' branch codes;
- ``checksums.json``, written last: every file's SHA-256.

The folder is written under a temporary name and renamed (:func:`~sik_ros.artifacts.
atomic_directory`). :func:`load_table` serves it only when every checksum, the key, the robot
and every array's type and shape agree (the KD-trees' nodes are checked too: the compiled
look-ups read them unchecked); anything else is damage: the folder is set aside
(``table.damaged-<time>-<pid>``, its reason beside it, never loaded) and the caller builds the
table again. Arrays are read with ``allow_pickle=False``: nothing in the cache is executed.
"""

from pathlib import Path
from typing import Callable, Dict, Optional
import zipfile

import numpy as np

from sik_ros.artifacts import (atomic_directory, check_robot_manifest, FORMAT_VERSION, read_json,
                               write_json_atomic)
from sik_ros.bundles.bundle import GoalModel, GOALS
from sik_ros.bundles.cache import ArmEntry, verify_checksums, write_checksums
from sik_ros.errors import ArtifactMismatch, CorruptArtifact
from sik_ros.kinematics.robot import Robot
from sik_ros.tables.index_table import IndexTable
from sik_ros.tables.seed_table import SeedTable

#: The entry's folder of the table, its manifest, and its ``kind``.
TABLE_FOLDER = 'table'
MANIFEST = 'table.json'
KIND = 'sik_configuration_table'
#: How far [rad] a stored configuration may lie outside the joint limits (its float16 rounding).
LIMIT_SLACK = 0.01


def table_folder(entry: ArmEntry) -> Path:
    """The entry's folder of the table of configurations."""
    return entry.path / TABLE_FOLDER


def save_table(entry: ArmEntry, robot: Robot, seconds: float,
               models: Dict[str, GoalModel]) -> Path:
    """Write the table of configurations of ``models`` (built for ``seconds``) to the entry.

    Raises:
        OSError: the folder cannot be written (the caller serves the table all the same).
    """
    table = models['position'].table
    seeds = models['pose'].seeds
    manifest = {'kind': KIND, 'format_version': FORMAT_VERSION, 'chain_key': entry.key,
                'sweep_seconds': float(seconds), 'robot': robot.manifest(),
                'table': table.manifest, 'seeds': None if seeds is None else seeds.manifest}
    with atomic_directory(table_folder(entry), force=True) as tmp:
        arrays = {'centers': table.centers, 'offsets': table.offsets,
                  'indices': table.indices.astype(np.float16), 'reach': table.reach.stored()}
        if table.orientations is not None:
            arrays['orientations'] = table.orientations
        np.savez(tmp / 'configurations.npz', **arrays)
        if seeds is not None:
            np.savez(tmp / 'seeds.npz', **seeds.state())
        write_json_atomic(tmp / MANIFEST, manifest)
        write_checksums(tmp)
    return table_folder(entry)


def load_table(entry: ArmEntry, robot: Robot, seconds: float,
               say: Callable[[str], None] = print) -> Optional[Dict[str, GoalModel]]:
    """The entry's table of configurations as the solver's parts, or None (build it then).

    None when there is none, or one sized to another ``sweep_time`` (replaced when the new one
    is saved); a damaged one (a checksum, the key, the robot, an array's type or shape) is set
    aside, with a line to ``say``, and None returned.
    """
    folder = table_folder(entry)
    if not folder.is_dir():  # written under another name and renamed: there whole, or not
        return None
    try:
        verify_checksums(folder, MANIFEST, 'table of configurations')
        manifest = read_json(folder / MANIFEST, 'table of configurations')
        if not isinstance(manifest, dict) or manifest.get('kind') != KIND \
                or manifest.get('format_version') != FORMAT_VERSION:
            raise CorruptArtifact(f'{folder / MANIFEST} is not a table of configurations of '
                                  f'this format')
        if manifest.get('chain_key') != entry.key:
            raise ArtifactMismatch(f'table of configurations {folder}: chain key', entry.key,
                                   manifest.get('chain_key'))
        if not isinstance(manifest.get('robot'), dict):
            raise CorruptArtifact(f'{folder / MANIFEST}: no robot manifest')
        check_robot_manifest(f'table of configurations {folder}', robot.manifest(),
                             manifest['robot'])
        for key in ('lower', 'upper'):
            if manifest['robot'].get(key) != getattr(robot, key).tolist():
                raise ArtifactMismatch(f'table of configurations {folder}: joint {key} limits',
                                       getattr(robot, key).tolist(),
                                       manifest['robot'].get(key))
        if manifest.get('sweep_seconds') != float(seconds):
            say(f'table of configurations: the cached one was sized to sweep_time '
                f'{manifest.get("sweep_seconds")} s, not {float(seconds)} s: built again')
            return None
        models = _models(folder, robot, manifest)
    except (CorruptArtifact, ArtifactMismatch) as exc:
        try:
            aside = entry.set_aside(str(exc), folder)
        except OSError as err:
            say(f'table of configurations {folder} is damaged ({exc}) and cannot be set aside '
                f'({err}): built again, not cached')
            return None
        say(f'table of configurations {folder} set aside as {aside.name} (never loaded): '
            f'{exc}; built again')
        return None
    except OSError as exc:  # unreadable (permissions): not served, left where it is
        say(f'table of configurations {folder} cannot be read ({exc}): built again')
        return None
    return models


def _arrays(path: Path) -> Dict[str, np.ndarray]:
    """Every array of an ``.npz`` file, read without pickles.

    Raises:
        CorruptArtifact: it cannot be read.
    """
    try:
        with np.load(path, allow_pickle=False) as f:
            return {k: f[k] for k in f.files}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        raise CorruptArtifact(f'cannot read {path}: {exc}') from exc


def _models(folder: Path, robot: Robot, manifest: Dict) -> Dict[str, GoalModel]:
    """The solver's parts of a checked folder's arrays (:func:`load_table`).

    Raises:
        CorruptArtifact: an array missing or of another type or shape than its manifest's.
    """
    what = f'table of configurations {folder}'
    tm = manifest.get('table')
    a = _arrays(folder / 'configurations.npz')
    try:
        centers, offsets, indices = a['centers'], a['offsets'], a['indices']
        cells, entries = int(tm['cells']), int(tm['entries'])
        orientations = a.get('orientations')
        ok = (centers.dtype == np.float64 and centers.shape == (cells, 3) and cells >= 1
              and offsets.dtype == np.int64 and offsets.shape == (cells + 1,)
              and offsets[0] == 0 and offsets[-1] == entries and np.all(np.diff(offsets) >= 1)
              and indices.dtype == np.float16 and indices.shape == (entries, robot.dof)
              and np.all(np.isfinite(centers)) and np.all(np.isfinite(indices))
              and np.all(indices >= robot.lower - LIMIT_SLACK)
              and np.all(indices <= robot.upper + LIMIT_SLACK)
              and bool(tm.get('orientations')) == (orientations is not None)
              and (orientations is None or (orientations.dtype == np.float32
                                            and orientations.shape == (entries, 4)
                                            and np.all(np.isfinite(orientations))
                                            and np.all(np.any(orientations != 0, axis=1)))))
    except (KeyError, TypeError, ValueError) as exc:
        raise CorruptArtifact(f'{what}: {exc}') from exc
    if not ok:
        raise CorruptArtifact(f'{what}: its arrays disagree with its manifest (shapes, types '
                              f'or values)')
    try:
        table = IndexTable(centers, offsets, indices.astype(np.float32), tm, orientations,
                           reach=a.get('reach'))
        table = table.with_postures(table.indices, robot.lower, robot.upper)
    except (ValueError, KeyError, TypeError) as exc:
        raise CorruptArtifact(f'{what}: {exc}') from exc
    seeds = None
    if manifest.get('seeds') is not None:
        if not isinstance(manifest['seeds'], dict):
            raise CorruptArtifact(f'{what}: its seed manifest is not a mapping')
        seeds = SeedTable.from_state(robot, _arrays(folder / 'seeds.npz'), manifest['seeds'])
    elif (folder / 'seeds.npz').exists():
        raise CorruptArtifact(f'{what}: a seed table its manifest does not list')
    return {goal: GoalModel(None, None, None, table, seeds if goal == 'pose' else None)
            for goal in GOALS}


def describe(models: Dict[str, GoalModel]) -> str:
    """``N configurations in M cells`` of a table of configurations' parts."""
    table = models['position'].table
    return f'{len(table.indices):,} configurations in {len(table):,} cells'
