"""A folder of trained baselines shipped with a bundle, with a manifest checked on load.

``sik-eval --baselines DIR`` reads the models of :data:`BASELINE_FILES` (and a ``psik/`` bundle). A
shipped folder also holds ``baselines.json``: the robot it was trained for and, per baseline, its
files with their sizes and sha256. :func:`ship_baselines` writes such a folder under a temporary
name and renames it into place; :func:`check_shipped` tells which baselines' files no longer match
the manifest (a truncated copy, a half-replaced file), so that they are refused instead of
evaluated.
"""

from pathlib import Path
import shutil
from typing import Dict, List, Mapping, Optional

from sik_ros.artifacts import (atomic_directory, file_sha256, FORMAT_VERSION, read_json,
                               robot_section, write_json_atomic)
from sik_ros.errors import CorruptArtifact, InvalidArgument

#: Baseline files looked for in a ``--baselines`` directory.
BASELINE_FILES = {'psik': 'psik.pt', 'fcn': 'fcn.pt', 'fcn_uni': 'fcn_uni.pt',
                  'anfis': 'anfis.pt'}
#: The manifest's file name.
MANIFEST = 'baselines.json'
#: The manifest's ``kind``.
KIND = 'sik_baselines'


def _entries(folder: Path, rel: List[str]) -> List[Dict]:
    """Each file's path relative to ``folder``, size [bytes] and sha256."""
    return [{'path': r, 'bytes': (folder / r).stat().st_size,
             'sha256': file_sha256(folder / r)} for r in rel]


def ship_baselines(out: Path, models: Mapping[str, Path], psik_bundle: Optional[Path],
                   robot: Mapping, force: bool = False) -> Path:
    """Copy trained baselines into ``out`` with their manifest, atomically.

    Args:
        out: the folder to write (``sik-eval --baselines``).
        models: ``{name: exported model file}`` for the single-solution baselines and ``psik``
            (a model alone), names of :data:`BASELINE_FILES`.
        psik_bundle: a bundle directory with PSIK's model and table (copied as ``psik/``), or
            None.
        robot: the robot manifest the models were trained for.
        force: replace an existing ``out``.

    Raises:
        InvalidArgument: an unknown baseline name or a missing file.
        ArtifactExists: ``out`` exists and ``force`` is false.
    """
    unknown = sorted(set(models) - set(BASELINE_FILES))
    if unknown:
        raise InvalidArgument(f'unknown baselines {unknown}; known: {sorted(BASELINE_FILES)}')
    sources = {BASELINE_FILES[name]: Path(p) for name, p in models.items()}
    for path in list(sources.values()) + ([Path(psik_bundle)] if psik_bundle else []):
        if not path.exists():
            raise InvalidArgument(f'{path} does not exist')
    with atomic_directory(Path(out), force=force) as tmp:
        files: Dict[str, List[str]] = {}
        for name, path in models.items():
            shutil.copyfile(path, tmp / BASELINE_FILES[name])
            files[name] = [BASELINE_FILES[name]]
        if psik_bundle:
            shutil.copytree(psik_bundle, tmp / 'psik')
            files['psik'] = sorted(str(p.relative_to(tmp)) for p in (tmp / 'psik').rglob('*')
                                   if p.is_file())
        write_json_atomic(tmp / MANIFEST, {
            'kind': KIND, 'format_version': FORMAT_VERSION, 'robot': dict(robot),
            'baselines': {name: _entries(tmp, rel) for name, rel in sorted(files.items())}})
    return Path(out)


def check_shipped(folder: Path) -> Dict[str, str]:
    """Baselines of a folder whose files do not match its manifest, and why.

    A folder without ``baselines.json`` (trained here, not shipped) has nothing to check.

    Returns:
        ``{name: reason}``; empty when every listed file matches.

    Raises:
        CorruptArtifact: an unreadable manifest, or not a baselines manifest.
    """
    path = Path(folder) / MANIFEST
    if not path.exists():
        return {}
    manifest = read_json(path, 'baselines manifest')
    if manifest.get('kind') != KIND or not isinstance(manifest.get('baselines'), dict):
        raise CorruptArtifact(f'{path} is not a baselines manifest')
    robot_section(manifest, str(path))
    bad = {}
    for name, entries in manifest['baselines'].items():
        for entry in entries:
            file = Path(folder) / entry['path']
            if not file.is_file():
                bad[name] = f'{file} is missing (listed in {MANIFEST})'
            elif file.stat().st_size != entry['bytes'] or file_sha256(file) != entry['sha256']:
                bad[name] = f'{file} does not match its sha256 in {MANIFEST}'
            if name in bad:
                break
    return bad
