"""Each arm's learned bundle, kept in the user's cache folder and checked before it is served.

An arm's entry is ``$XDG_CACHE_HOME/sik_ros/arms/<key>/`` (``~/.cache`` when the variable is
unset), ``<key>`` the hash of what defines its chain
(:func:`~sik_ros.kinematics.arm_description.chain_key`). It holds:

- ``arm.urdf``: the robot_description, its collision meshes resolved here
  (:func:`~sik_ros.kinematics.arm_description.arm_files`), written once: a later description
  of the same chain (other links changed) is served from the file already there;
- ``bundle/``: a ``sik-build`` bundle with ``checksums.json`` (every file's SHA-256, written
  last): an entry without it is unfinished, one whose files disagree with it is damaged;
- ``build/``: the build's work folder (dataset, checkpoints), resumable, removed once done;
- ``table/``: the table of configurations that answers before the bundle, as built at the
  first start (:mod:`~sik_ros.bundles.table_cache`), with its ``checksums.json``: a restart
  loads it instead of sweeping again;
- ``lock``: held (``flock``) by the one process building the entry; another one serves the
  table of configurations and waits for the bundle.

A damaged bundle is renamed ``bundle.damaged-<time>`` (kept for a look, never loaded) and built
again (a damaged table alike: ``table.damaged-<time>``). :func:`write_checksums` is what
``sik-build`` calls on every bundle it finishes, so a bundle built elsewhere can be copied into
an entry (``sik-build`` prints the key).
"""

import contextlib
import fcntl
import os
from pathlib import Path
import time
from typing import Dict, IO, Iterator, Optional

from sik_ros.artifacts import file_sha256, FORMAT_VERSION, read_json, write_json_atomic
from sik_ros.errors import CorruptArtifact

#: The checksum file of a finished bundle.
CHECKSUMS = 'checksums.json'
#: Version of an entry's layout (part of the folder name, so a new layout never reads an old).
CACHE_VERSION = 1


def cache_root(base: Optional[str] = None) -> Path:
    """The folder of every arm's entry: ``<base or $XDG_CACHE_HOME or ~/.cache>/sik_ros``."""
    if not base:
        base = os.environ.get('XDG_CACHE_HOME') or str(Path.home() / '.cache')
    return Path(base).expanduser() / 'sik_ros' / f'arms-v{CACHE_VERSION}-f{FORMAT_VERSION}'


def write_checksums(bundle: Path) -> Path:
    """Record every file of a bundle folder (its ``bundle.json`` too) in ``checksums.json``."""
    bundle = Path(bundle)
    files = {p.relative_to(bundle).as_posix(): file_sha256(p)
             for p in sorted(bundle.rglob('*')) if p.is_file() and p.name != CHECKSUMS
             and not p.name.startswith('.')}
    write_json_atomic(bundle / CHECKSUMS, {'format_version': FORMAT_VERSION, 'files': files})
    return bundle / CHECKSUMS


def verify_checksums(bundle: Path, manifest: str = 'bundle.json', what: str = 'bundle') -> None:
    """Check a bundle folder (or another folder of ``what``) against its ``checksums.json``.

    ``manifest``: the file the record must list (the folder's own manifest).

    Raises:
        CorruptArtifact: no checksum file (unfinished), a missing file, or one that changed.
    """
    bundle = Path(bundle)
    record = read_json(bundle / CHECKSUMS, f'{what} {bundle} (unfinished: no {CHECKSUMS})')
    files = record.get('files') if isinstance(record, dict) else None
    if not isinstance(files, dict) or manifest not in files:
        raise CorruptArtifact(f'{what} {bundle}: {CHECKSUMS} lists no {manifest}')
    for name, digest in files.items():
        path = bundle / name
        if not isinstance(name, str) or '..' in Path(name).parts or not path.is_file():
            raise CorruptArtifact(f'{what} {bundle}: {name} is missing')
        if file_sha256(path) != digest:
            raise CorruptArtifact(f'{what} {bundle}: {name} changed since it was written '
                                  f'(its checksum differs)')


class ArmEntry:
    """One arm's cache entry (see the module's layout)."""

    def __init__(self, root: Path, key: str):
        self.key = key
        self.path = Path(root) / key
        self.bundle = self.path / 'bundle'
        self.work = self.path / 'build'
        self.urdf = self.path / 'arm.urdf'
        self._lock_file = None

    def ready(self) -> bool:
        """Whether a finished bundle is there (not checked: :meth:`checked_bundle` checks)."""
        return (self.bundle / CHECKSUMS).is_file()

    def checked_bundle(self) -> Optional[Path]:
        """The bundle when it is finished and intact; a damaged one is set aside (None).

        An unfinished bundle (no checksums yet) is left alone: its builder may be writing it.
        """
        if not self.bundle.is_dir() or not self.ready():
            return None
        try:
            verify_checksums(self.bundle)
        except CorruptArtifact as exc:
            self.set_aside(str(exc))
            return None
        return self.bundle

    def set_aside(self, reason: str, folder: Optional[Path] = None) -> Path:
        """Rename a damaged bundle (or ``folder``) out of the way, its reason beside it.

        It is never loaded again: ``<name>.damaged-<time>-<pid>`` and ``...reason.txt``.
        """
        folder = self.bundle if folder is None else Path(folder)
        aside = self.path / (f'{folder.name}.damaged-{time.strftime("%Y%m%dT%H%M%S")}-'
                             f'{os.getpid()}')
        os.replace(folder, aside)
        (aside.parent / f'{aside.name}.reason.txt').write_text(reason + '\n')
        return aside

    def try_lock(self) -> Optional[IO]:
        """Take the entry's build lock, without waiting: its handle, or None when held.

        The lock is the kernel's (``flock``): a process that dies lets go of it.
        """
        self.path.mkdir(parents=True, exist_ok=True)
        f = open(self.path / 'lock', 'a+')
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.close()
            return None
        return f

    @staticmethod
    def unlock(handle: IO) -> None:
        """Let go of a lock :meth:`try_lock` took."""
        fcntl.flock(handle, fcntl.LOCK_UN)
        handle.close()

    @contextlib.contextmanager
    def building(self) -> Iterator[bool]:
        """Hold the entry's build lock while the block runs; yields whether it was taken."""
        handle = self.try_lock()
        try:
            yield handle is not None
        finally:
            if handle is not None:
                self.unlock(handle)

    def status(self) -> Dict:
        """The build's progress as its builder last wrote it (empty when none)."""
        try:
            return read_json(self.work / 'progress.json', 'build progress')
        except CorruptArtifact:
            return {}
