"""An arm served from its robot_description: checked, keyed, its solver ready in seconds.

:func:`prepare_arm` checks a description and two frames before anything is written (bad input
leaves the cache untouched), keys the chain and writes its cache entry's URDF;
:func:`first_solver` gives the solver that answers at once: the learned bundle of the entry when
it is there and intact, else the arm's table of collected configurations
(:mod:`~sik_ros.bundles.sweep_models`), which answers exactly with no training: built at the
arm's first start and kept in the entry, loaded at the next (:mod:`~sik_ros.bundles.table_cache`).

A learned model replaces the table only where it answers at least as well: :func:`compare`
solves the same targets with both (paired, in turn) and :func:`keep_verdict` records the
outcome in the entry (``verdict.json``, tied to the bundle's checksums), so that a restart
serves what won without measuring again. A model trained briefly (a short ``learning_time``)
can start refinement from worse postures than the arm's own collected configurations.
"""

from dataclasses import dataclass, field
import hashlib
from pathlib import Path
import tempfile
import threading
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np

from sik_ros.artifacts import file_sha256, read_json, write_json_atomic, write_text_atomic
from sik_ros.bundles.bundle import load_bundle
from sik_ros.bundles.cache import ArmEntry, cache_root, CHECKSUMS
from sik_ros.bundles.sweep_models import sweep_models
from sik_ros.bundles.table_cache import describe, load_table, save_table
from sik_ros.errors import SikError
from sik_ros.kinematics.arm_description import (arm_files, arm_robot, chain_key, check_chain,
                                                collision_text, Description, mesh_folders,
                                                read_description)
from sik_ros.kinematics.robot import Robot
from sik_ros.solver import SelectiveIK, SolverConfig

#: Seconds the table of configurations may take by default.
SWEEP_SECONDS = 3.0
#: Targets per goal kind of :func:`compare`, and the distinct solutions asked.
COMPARE_TARGETS = 24
COMPARE_SOLUTIONS = 16


@dataclass
class Arm:
    """An arm from a robot_description.

    Attributes:
        robot: the chain, loaded from the entry's URDF.
        key: the chain's cache key.
        entry: its cache entry.
        missing_meshes: collision meshes not found here (those parts have no geometry).
        notes: what the loading found worth a line on the log.
        table_built, table_loaded: how many times its table of configurations was built
            (swept) and loaded from the entry (:func:`table_solver`).
        saving: the thread writing a built table to the entry (None when none was built).
    """

    robot: Robot
    key: str
    entry: ArmEntry
    missing_meshes: List[str] = field(default_factory=list)
    notes: List[str] = field(default_factory=list)
    table_built: int = 0
    table_loaded: int = 0
    saving: Optional[threading.Thread] = None


def prepare_arm(text: str, base: str, tip: str, cache: Optional[str] = None) -> Arm:
    """Check a description and its chain, key it, and write its cache entry's URDF.

    Everything is checked on a copy in a temporary folder first: a description or chain that
    cannot be served writes nothing to the cache.

    Args:
        text: the URDF (or xacro) text.
        base: the base frame.
        tip: the tip frame.
        cache: the cache's base folder (None or empty: ``$XDG_CACHE_HOME``, ``~/.cache``).

    Raises:
        SikError: the description or the chain cannot be served (one line saying why).
    """
    desc = read_description(text)
    check_chain(desc, base, tip)
    root = cache_root(cache)
    resolved, missing = collision_text(desc.text, mesh_folders())
    index = root / 'index' / hashlib.sha256(
        '\0'.join((resolved, base, tip)).encode()).hexdigest()
    known = _known(desc, root, index, resolved, base, tip)
    if known is not None:  # this description was served before: its entry's robot, loaded once
        return Arm(known[0], known[1], ArmEntry(root, known[1]), missing, [])
    with tempfile.TemporaryDirectory(prefix='sik_arm_') as tmp:
        urdf, missing = arm_files(desc, Path(tmp))
        key = chain_key(arm_robot(desc, urdf, base, tip))
    entry = ArmEntry(root, key)
    notes = []
    robot = _entry_robot(desc, entry, key, base, tip, notes)
    if robot is None:
        entry.path.mkdir(parents=True, exist_ok=True)
        arm_files(desc, entry.path)
        robot = arm_robot(desc, entry.urdf, base, tip)
    index.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(index, key + '\n')
    return Arm(robot, key, entry, missing, notes)


def _known(desc: Description, root: Path, index: Path, resolved: str, base: str, tip: str
           ) -> Optional[Tuple[Robot, str]]:
    """The robot and key of a description served before (the same text, meshes and frames).

    Read from the entry the index names, when its URDF is that text and its chain that key;
    None otherwise (the caller keys the description afresh).
    """
    try:
        key = index.read_text().strip()
        urdf = ArmEntry(root, key).urdf
        if not key or urdf.read_text() != resolved:
            return None
        robot = arm_robot(desc, urdf, base, tip)
    except (OSError, SikError):
        return None
    return (robot, key) if chain_key(robot) == key else None


def _entry_robot(desc: Description, entry: ArmEntry, key: str, base: str, tip: str,
                 notes: List[str]) -> Optional[Robot]:
    """The robot of the entry's URDF already there, when it has the same chain (else None)."""
    if not entry.urdf.is_file():
        return None
    try:
        robot = arm_robot(read_description(entry.urdf.read_text()), entry.urdf, base, tip)
    except (SikError, OSError):
        robot = None
    if robot is not None and chain_key(robot) == key:
        return robot
    notes.append(f'cache entry {entry.path}: its URDF did not match its key; written again')
    return None


def load_learned(arm: Arm, config: SolverConfig) -> Optional[SelectiveIK]:
    """The entry's learned bundle as a solver, when finished and intact; None otherwise.

    A bundle that fails its checksums or its checks on load is set aside (never loaded again).
    """
    bundle = arm.entry.checked_bundle()
    if bundle is None:
        return None
    try:
        path, robot, models = load_bundle(bundle, arm.robot)
    except SikError as exc:
        arm.notes.append(f'cached bundle {bundle} set aside: {exc}')
        arm.entry.set_aside(str(exc))
        return None
    return SelectiveIK(robot, models, config, path)


def compare(table: SelectiveIK, learned: SelectiveIK, targets: int = COMPARE_TARGETS,
            seed: int = 0) -> Dict[str, Dict[str, Dict[str, float]]]:
    """Success and distinct exact solutions (median) of both solvers on the same targets.

    Targets: FK of configurations drawn uniformly within the limits, each goal kind, solved by
    one solver then the other.
    """
    robot = table.robot
    q = np.random.default_rng(seed).uniform(robot.lower, robot.upper, (targets, robot.dof))
    out: Dict[str, Dict[str, Dict[str, float]]] = {'table': {}, 'learned': {}}
    for goal in sorted(set(table.goals) & set(learned.goals)):
        figures = {'table': ([], []), 'learned': ([], [])}
        for qi in q:
            p, quat = robot.fk(qi)
            for name, ik in (('table', table), ('learned', learned)):
                res = ik.solve(p, quat if goal == 'pose' else None, COMPARE_SOLUTIONS)
                figures[name][0].append(float(res.success))
                figures[name][1].append(sum(s.converged for s in res.solutions))
        for name, (ok, distinct) in figures.items():
            out[name][goal] = {'success': float(np.mean(ok)),
                               'distinct_median': float(np.median(distinct))}
    return out


def learned_not_worse(figures: Dict) -> bool:
    """Whether the learned model answered every goal kind as well as the table did."""
    return all(figures['learned'][g]['success'] >= f['success']
               and figures['learned'][g]['distinct_median'] >= f['distinct_median']
               for g, f in figures['table'].items())


def keep_verdict(arm: Arm, figures: Dict) -> bool:
    """Record :func:`compare`'s outcome in the entry (for its bundle); the verdict."""
    better = learned_not_worse(figures)
    write_json_atomic(arm.entry.path / 'verdict.json', {
        'checksums_sha256': file_sha256(arm.entry.bundle / CHECKSUMS),
        'learned_not_worse': better, 'figures': figures})
    return better


def table_preferred(arm: Arm) -> bool:
    """Whether the entry's verdict for its bundle chose the table of configurations."""
    try:
        verdict = read_json(arm.entry.path / 'verdict.json', 'verdict')
        same = verdict.get('checksums_sha256') == file_sha256(arm.entry.bundle / CHECKSUMS)
    except (SikError, OSError):
        return False
    return same and verdict.get('learned_not_worse') is False


def table_solver(arm: Arm, config: SolverConfig, seconds: float = SWEEP_SECONDS,
                 say: Callable[[str], None] = print) -> SelectiveIK:
    """The arm's table of configurations as a solver (``seconds`` of sweep and table).

    Loaded from the entry when a start built it before (:mod:`~sik_ros.bundles.table_cache`:
    checked, a damaged one set aside); else built, and written to the entry by a thread of its
    own (``arm.saving``) while the solver answers.
    """
    models = load_table(arm.entry, arm.robot, seconds, say)
    if models is not None:
        arm.table_loaded += 1
        say(f'table of configurations: loaded from the cache ({describe(models)})')
        return SelectiveIK(arm.robot, models, config)
    models = sweep_models(arm.robot, seconds)
    arm.table_built += 1
    say(f'table of configurations: {describe(models)}')

    def save() -> None:
        try:
            save_table(arm.entry, arm.robot, seconds, models)
        except OSError as exc:  # a read-only or full cache: served all the same
            say(f'table of configurations not cached ({exc}): the next start builds it')

    arm.saving = threading.Thread(target=save, name='sik_table_cache')
    arm.saving.start()
    return SelectiveIK(arm.robot, models, config)


def first_solver(arm: Arm, config: SolverConfig, seconds: float = SWEEP_SECONDS,
                 say: Callable[[str], None] = print) -> Tuple[SelectiveIK, bool]:
    """The solver that answers first, and whether it is the learned one.

    The learned bundle of the entry when it is there (and its verdict did not prefer the
    table); else the arm's table of configurations (``seconds`` of sweep and table).
    """
    learned = load_learned(arm, config)
    if learned is not None and not table_preferred(arm):
        return learned, True
    if learned is not None:
        say('the learned model answered worse than the table of configurations when it was '
            'built: serving the table')
    return table_solver(arm, config, seconds, say), False
