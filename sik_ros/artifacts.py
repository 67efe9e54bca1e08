"""Artifacts on disk: manifests, atomic writes, and checks on load.

Every artifact (dataset directory, checkpoint, index table, bundle) carries a JSON manifest. Files
are written under a temporary name in the same directory and renamed into place, so an interrupted
write never leaves something that looks complete under the final name.
"""

import contextlib
import hashlib
import json
import os
from pathlib import Path
import shutil
import tempfile
from typing import Iterator, Mapping

import numpy as np

from sik_ros.errors import ArtifactExists, ArtifactMismatch, CorruptArtifact

#: Version of the on-disk formats written by this code.
FORMAT_VERSION = 1

#: Keys of a robot manifest that must agree between artifacts used together.
ROBOT_KEYS = ('robot', 'urdf_sha256', 'base_frame', 'tip_frame', 'joint_names')


def file_sha256(path: Path) -> str:
    """The hex SHA-256 of a file's bytes, read in 1 MiB blocks."""
    digest = hashlib.sha256()
    with open(path, 'rb') as f:
        for block in iter(lambda: f.read(1 << 20), b''):
            digest.update(block)
    return digest.hexdigest()


def library_versions() -> dict:
    """Versions of the libraries that shape an artifact's content (those installed)."""
    import numpy
    versions = {'numpy': numpy.__version__}
    try:  # a chain file's model trains where there is no Pinocchio (a GPU machine)
        import pinocchio
        versions['pinocchio'] = pinocchio.__version__
    except ImportError:
        pass
    try:
        import torch
        versions['torch'] = str(torch.__version__)
    except ImportError:  # pragma: no cover - torch is a hard dependency
        pass
    from sik_ros import __version__
    versions['sik_ros'] = __version__
    return versions


@contextlib.contextmanager
def atomic_write(path: Path) -> Iterator[Path]:
    """A temporary path beside ``path`` to write to; renamed onto ``path`` when the block ends.

    The temporary name keeps ``path``'s suffix (NumPy and Matplotlib choose the format by it).
    If the block raises, the temporary file is removed and ``path`` is left as it was.

    Yields:
        the temporary path to write.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f'.{path.stem}.', suffix=f'.tmp{path.suffix}',
                               dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_text_atomic(path: Path, text: str) -> None:
    """Write a text file through :func:`atomic_write`."""
    with atomic_write(path) as tmp:
        tmp.write_text(text)


def write_json_atomic(path: Path, data: Mapping) -> None:
    """Write JSON to ``path`` through :func:`atomic_write`."""
    write_text_atomic(path, json.dumps(data, indent=2, sort_keys=True) + '\n')


def read_json(path: Path, what: str) -> dict:
    """Read a JSON manifest, turning a missing or unreadable file into :class:`CorruptArtifact`."""
    path = Path(path)
    if not path.is_file():
        raise CorruptArtifact(f'{what}: {path} is missing (incomplete or not a sik_ros artifact)')
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise CorruptArtifact(f'{what}: cannot read {path}: {exc}') from exc


@contextlib.contextmanager
def atomic_directory(out: Path, force: bool = False) -> Iterator[Path]:
    """Build a directory under a temporary name, then rename it to ``out``.

    Args:
        out: final directory path.
        force: replace an existing ``out``; otherwise an existing ``out`` is refused.

    Yields:
        the temporary directory to fill.

    Raises:
        ArtifactExists: ``out`` exists and ``force`` is false.
    """
    out = Path(out)
    if out.exists() and not force:
        raise ArtifactExists(f'{out} already exists (use --force to replace it)')
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f'.{out.name}.', suffix='.partial', dir=out.parent))
    try:
        yield tmp
        if out.exists():
            old = out.with_name(f'.{out.name}.old-{os.getpid()}')
            os.replace(out, old)
            os.replace(tmp, out)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def range_codes(values: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                dtype: type = np.uint8) -> np.ndarray:
    """Values quantised over ``lower``..``upper`` per column to unsigned integer codes.

    The codes' whole range spans the interval: 8 bits steps of 1/255 of it, 16 bits 1/65535.
    """
    levels = np.iinfo(dtype).max
    codes = np.round((np.asarray(values) - lower) / (upper - lower) * levels)
    return np.clip(codes, 0, levels).astype(dtype)


def range_values(codes: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """The values (float64) that :func:`range_codes` stood for."""
    return lower + codes.astype(np.float32) / np.iinfo(codes.dtype).max * (upper - lower)


def robot_section(content: Mapping, what: str) -> dict:
    """The ``robot`` manifest of an artifact's ``content``, checked for its names.

    Raises:
        CorruptArtifact: it is not a mapping with ``robot``, ``base_frame`` and ``tip_frame``.
    """
    robot = content.get('robot')
    if not isinstance(robot, dict) or not all(
            isinstance(robot.get(k), str) for k in ('robot', 'base_frame', 'tip_frame')):
        raise CorruptArtifact(f'{what}: "robot" must be a robot manifest with robot, '
                              f'base_frame and tip_frame')
    return robot


def check_robot_manifest(what: str, expected: Mapping, found: Mapping) -> None:
    """Refuse an artifact whose robot identity differs from the expected one.

    Raises:
        ArtifactMismatch: naming the first key that differs.
    """
    for key in ROBOT_KEYS:
        if key in expected and expected.get(key) != found.get(key):
            raise ArtifactMismatch(f'{what}: {key}', expected.get(key), found.get(key))
