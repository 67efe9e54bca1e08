"""Bundles: a directory with one model and one index table per goal kind, and ``bundle.json``.

``bundle.json`` names the robot (its manifest: name or URDF, frames, joints) and, per goal kind
(``position``, ``pose``), the model file and its table; the pose model of an arm with seven
joints or fewer also has a seed table (:mod:`sik_ros.tables.seed_table`); ``trained`` says
where, how long and on how many samples each model was trained. :func:`build_bundle` makes one
from trained models and a dataset (``sik-index --bundle`` and the tests use it);
:func:`load_bundle` reads one back, checking every file against the manifest. A SIK model also
gets its NumPy twin (``twin``: :mod:`sik_ros.learning.twins`), which a bundle loads from without
importing torch; a bundle without twins (the bundled Panda's) loads its models through torch.
"""

from dataclasses import dataclass
from pathlib import Path
import shutil
from typing import Any, Callable, Dict, Mapping, Optional, Tuple, Union

from sik_ros.artifacts import (atomic_write, check_robot_manifest, FORMAT_VERSION, read_json,
                               robot_section, write_json_atomic)
from sik_ros.defaults import TableConfig
from sik_ros.errors import ArtifactMismatch, CorruptArtifact
from sik_ros.kinematics.robot import Robot
from sik_ros.kinematics.robots import robot_from_manifest
from sik_ros.learning.twins import load_twin
from sik_ros.tables.dataset import Dataset
from sik_ros.tables.index_table import IndexTable, PostureTable
from sik_ros.tables.seed_table import default_rows, SeedTable

#: The bundles shipped inside the package, one directory per robot name.
BUNDLES = Path(__file__).resolve().parent
#: Goal kinds a bundle may hold.
GOALS = ('position', 'pose')


@dataclass
class GoalModel:
    """What the solver holds per goal kind: the network, its configs and its table.

    Attributes:
        model: the SIK/PSIK module, in eval mode, or its NumPy twin
            (:class:`~sik_ros.learning.twins.NumpySIK`); None for a table of configurations.
        cfg: its :class:`~sik_ros.learning.models.ModelConfig`.
        norm: its :class:`~sik_ros.learning.models.Normalizer`.
        table: the posture indices to decode (an :class:`IndexTable` or another
            :class:`PostureTable`).
        seeds: dataset configurations by tip pose, where isolated pose solutions start
            (arms of six joints or fewer), or None.
    """

    model: Any
    cfg: object
    norm: object
    table: PostureTable
    seeds: Optional[SeedTable] = None


def resolve_bundle(bundle: Union[str, Path]) -> Path:
    """A bundle directory from a path or the name of a bundled one (``panda``).

    Raises:
        CorruptArtifact: neither a directory nor a bundled name.
    """
    path = Path(bundle)
    if path.is_dir():
        return path
    if (BUNDLES / str(bundle)).is_dir():
        return BUNDLES / str(bundle)
    known = sorted(p.name for p in BUNDLES.iterdir() if p.is_dir()) if BUNDLES.is_dir() else []
    raise CorruptArtifact(f'no bundle {bundle!r}: not a directory, and the bundled models are '
                          f'{known}')


def read_bundle_manifest(path: Path) -> Dict:
    """``bundle.json`` of a bundle directory, checked for the keys and types it must have.

    Raises:
        CorruptArtifact: missing, unreadable or malformed, naming the file and the key.
    """
    file = Path(path) / 'bundle.json'
    manifest = read_json(file, f'bundle {path}')
    if not isinstance(manifest, dict) or manifest.get('kind') != 'sik_bundle':
        raise CorruptArtifact(f'{file} is not a sik_ros bundle manifest')
    robot_section(manifest, str(file))
    models = manifest.get('models')
    if not isinstance(models, dict) or not models:
        raise CorruptArtifact(f'{file}: "models" must map goal kinds to their files')
    for goal, files in models.items():
        if goal not in GOALS or not isinstance(files, dict) or not all(
                isinstance(files.get(k), str) and files.get(k)
                for k in ('model', 'table') + (('seeds',) if 'seeds' in files else ())):
            raise CorruptArtifact(f'{file}: models[{goal!r}] must be a goal kind {GOALS} with '
                                  f'"model" and "table" (and optionally "seeds") file names')
    return manifest


def load_bundle(bundle: Union[str, Path], robot: Optional[Robot] = None
                ) -> Tuple[Path, Robot, Dict[str, GoalModel]]:
    """The directory, robot and per-goal models of a bundle, every file checked.

    Args:
        bundle: a bundle directory or the name of a bundled one.
        robot: the arm, when the caller has it already (an arm from robot_description): the
            bundle must have been made for it (same name, URDF content, frames and joints;
            the URDF file it names need not exist here). None: the arm the bundle names.

    Raises:
        CorruptArtifact: a missing or damaged file.
        ArtifactMismatch: files made for another robot or model.
    """
    path = resolve_bundle(bundle)
    manifest = read_bundle_manifest(path)
    rm = manifest['robot']
    if robot is None:
        robot = robot_from_manifest(rm, f'bundle {path}')
    else:
        check_robot_manifest(f'bundle {path}', robot.manifest(), rm)
    models = {}
    for goal, files in manifest['models'].items():
        if 'twin' in files:  # no torch
            model, cfg, norm, own = load_twin(path / files['twin'])
            signature = own['signature']
        else:
            from sik_ros.learning.checkpoints import (load_checkpoint, model_from_checkpoint,
                                                      model_signature)
            own = load_checkpoint(path / files['model'])
            model, cfg, norm = model_from_checkpoint(own)
            signature = model_signature(own)
        check_robot_manifest(f'model {files["model"]}', robot.manifest(), own['robot'])
        if cfg.goal != goal or cfg.kind not in ('sik', 'psik'):
            raise ArtifactMismatch(f'bundle {path}: model for {goal} goals', goal,
                                   f'{cfg.kind}/{cfg.goal}')
        table = IndexTable.load(path / files['table'], robot.manifest(), signature)
        seeds = SeedTable.load(path / files['seeds'], robot) if 'seeds' in files else None
        models[goal] = GoalModel(model, cfg, norm, table, seeds)
    return path, robot, models


def bundle_files(goal: str) -> Dict[str, str]:
    """The file names of a goal kind's model, table and seed table inside a bundle."""
    return {'model': f'sik_{goal}.pt', 'table': f'sik_{goal}_table.npz',
            'seeds': f'sik_{goal}_seeds.npz', 'twin': f'sik_{goal}_twin.npz'}


def add_to_bundle(bundle: Path, robot_manifest: Dict, goal: str, model_file: Path,
                  table_file: Path, seeds_file: Optional[Path] = None) -> Path:
    """Copy a model and its table (and seed table) into a bundle, listed in ``bundle.json``.

    A seed table the goal already had stays listed when none is given: it depends on the robot
    and the data only, not on the model. ``trained`` records, per goal kind, where, how long
    and on how many samples its model was trained
    (:func:`~sik_ros.learning.provenance.trained_summary`).

    Files are copied under temporary names and renamed; the manifest is rewritten atomically
    last, so a reader never sees a manifest naming a half-written file.
    """
    from sik_ros.learning.checkpoints import load_checkpoint
    from sik_ros.learning.provenance import trained_summary
    from sik_ros.learning.twins import write_twin
    bundle = Path(bundle)
    bundle.mkdir(parents=True, exist_ok=True)
    if (bundle / 'bundle.json').exists():
        manifest = read_bundle_manifest(bundle)
        if manifest['robot'] != robot_manifest:
            raise ArtifactMismatch(f'bundle {bundle}: robot', manifest['robot'], robot_manifest)
    else:
        manifest = {'kind': 'sik_bundle', 'format_version': FORMAT_VERSION,
                    'robot': robot_manifest, 'models': {}}
    names = bundle_files(goal)
    files = {'model': model_file, 'table': table_file}
    if seeds_file is not None:
        files['seeds'] = seeds_file
    elif 'seeds' in manifest['models'].get(goal, {}):
        files['seeds'] = bundle / manifest['models'][goal]['seeds']
    for key, src in files.items():
        dst = bundle / names[key]
        if Path(src).resolve() != dst.resolve():
            with atomic_write(dst) as tmp:
                shutil.copyfile(src, tmp)
    manifest['models'][goal] = {key: names[key] for key in files}
    ckpt = load_checkpoint(model_file)
    if write_twin(ckpt, bundle / names['twin']) is not None:
        manifest['models'][goal]['twin'] = names['twin']
    # where, how long and on how many samples the model was trained (sik-eval shows it)
    manifest.setdefault('trained', {})[goal] = trained_summary(ckpt)
    write_json_atomic(bundle / 'bundle.json', manifest)
    return bundle


def build_bundle(out: Path, robot: Robot, models: Mapping[str, Path], dataset: Dataset,
                 cfg: TableConfig = TableConfig(), orientations: bool = True,
                 progress: Optional[Callable[[int], None]] = None,
                 seed_rows: Optional[int] = -1) -> Path:
    """A bundle from trained models: each one's table built over ``dataset``, then bundled.

    Args:
        out: the bundle directory (created or added to).
        robot: the robot of the models and the dataset.
        models: model or checkpoint file (``.pt``) per goal kind.
        dataset: the dataset the tables are built from.
        cfg: the tables' cells.
        orientations: keep each index's tip orientation in the tables.
        progress: called with the rows encoded, chunk by chunk.
        seed_rows: configurations of the pose model's seed table, for an arm of seven joints
            or fewer (-1: :func:`~sik_ros.tables.seed_table.default_rows`; None or 0: none).

    Returns:
        ``out``.
    """
    from sik_ros.learning.checkpoints import load_checkpoint
    from sik_ros.learning.indexing import build_table
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if default_rows(robot) is None:
        seed_rows = None  # an arm of more than 7 joints: its pose solutions walk instead
    elif seed_rows is not None and seed_rows < 0:
        seed_rows = default_rows(robot)
    for goal, model_file in models.items():
        table = build_table(load_checkpoint(model_file), robot, dataset, cfg, orientations,
                            progress=progress)
        if table.manifest['goal'] != goal:
            raise ArtifactMismatch(f'{model_file}: goal', goal, table.manifest['goal'])
        table_file = table.save(out / bundle_files(goal)['table'])
        seeds_file = None
        if goal == 'pose' and seed_rows:
            seeds_file = SeedTable.build(robot, dataset, seed_rows).save(
                out / bundle_files(goal)['seeds'])
        add_to_bundle(out, robot.manifest(), goal, Path(model_file), table_file, seeds_file)
    return out
