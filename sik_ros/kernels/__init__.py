"""Compiled kernels (numba): kinematics, damped least squares, small network calls.

The kernels take arrays and scalars, allocate nothing per joint or per step, write into arrays
the caller owns and release the GIL. Their argument types are declared, so they are compiled
(or loaded from numba's disk cache) when this package is imported, never inside a request; a
call with other types is refused instead of compiled. The cache lives in ``__pycache__`` beside
the sources; when the package's folder is read-only, in numba's user cache directory
(``~/.cache/numba``); when that is not writable either, in the system's temporary directory;
``NUMBA_CACHE_DIR`` chooses another.
"""

import os
from pathlib import Path
import tempfile

from numba.core import config
from numba.misc.appdirs import AppDirs
import numpy as np


def _writable(folder: Path) -> bool:
    """Whether ``folder`` (or the nearest existing folder above it) can be written."""
    while not folder.exists():
        folder = folder.parent
    return os.access(folder, os.W_OK)


def _cache_folder() -> None:
    """A writable cache folder for numba when neither its usual two are writable.

    numba caches beside the sources, else in the user cache directory; with both read-only
    (an installed package, a user without a home) it would refuse to compile. Then the
    system's temporary directory is used, one folder per user.
    """
    if config.CACHE_DIR:
        return
    user = Path(AppDirs(appname='numba', appauthor=False).user_cache_dir)
    if _writable(Path(__file__).parent / '__pycache__') or _writable(user):
        return
    config.CACHE_DIR = os.path.join(tempfile.gettempdir(), f'sik_ros-numba-{os.getuid()}')


_cache_folder()


def as_arg(a, dtype=np.float64) -> np.ndarray:
    """``a`` as the kernels take it: C-contiguous, writeable, of ``dtype`` (copied if need be)."""
    a = np.asarray(a, dtype=dtype)
    if not (a.flags.c_contiguous and a.flags.writeable):
        a = np.array(a, dtype=dtype, order='C')
    return a


from sik_ros.kernels.chain import chain_frames, fk_many, jac_many  # noqa: E402,I100
from sik_ros.kernels.dls import follow_rows, refine_rows  # noqa: E402
from sik_ros.kernels.mlp import mlp_rows, pack_layers  # noqa: E402

__all__ = ['as_arg', 'chain_frames', 'fk_many', 'follow_rows', 'jac_many', 'mlp_rows',
           'pack_layers', 'refine_rows']
