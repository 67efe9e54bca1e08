"""Where numba keeps the compiled kernels, and whether it keeps them at all (:data:`CACHE`).

numba caches beside the sources (``__pycache__``), else in the user cache directory
(``~/.cache/numba``); ``NUMBA_CACHE_DIR`` chooses another. When neither usual folder can be
written (an installed package, a user without a home), a folder of the system's temporary
directory private to the user is used: created with mode 0700, and used only while it is a
real folder owned by the user that nobody else can write. numba loads pickled data from its
cache, so a folder another user could have made or could write is never used: then the
kernels are compiled in memory at every start (:data:`CACHE` false).
"""

import os
from pathlib import Path
import stat
import tempfile

from numba.core import config
from numba.misc.appdirs import AppDirs


def _writable(folder: Path) -> bool:
    """Whether ``folder`` (or the nearest existing folder above it) can be written."""
    while not folder.exists():
        folder = folder.parent
    return os.access(folder, os.W_OK)


def private_folder(path: Path) -> bool:
    """Make ``path`` a folder only this user can use (mode 0700); whether it is one.

    An existing ``path`` is accepted only if it is a folder, not a link, owned by this user,
    with no permission for group or others.
    """
    try:
        os.mkdir(path, 0o700)
    except FileExistsError:
        pass
    except OSError:
        return False
    try:
        st = os.lstat(path)
    except OSError:
        return False
    return (stat.S_ISDIR(st.st_mode) and st.st_uid == os.getuid()
            and stat.S_IMODE(st.st_mode) & 0o077 == 0)


def _configure() -> bool:
    """Choose numba's cache folder; whether the kernels are cached on disk."""
    if config.CACHE_DIR:
        return True
    user = Path(AppDirs(appname='numba', appauthor=False).user_cache_dir)
    if _writable(Path(__file__).parent / '__pycache__') or _writable(user):
        return True
    folder = Path(tempfile.gettempdir()) / f'sik_ros-numba-{os.getuid()}'
    if private_folder(folder):
        config.CACHE_DIR = str(folder)
        return True
    return False


#: Whether the kernels are cached on disk (the ``cache`` flag of every kernel's decorator).
CACHE = _configure()
