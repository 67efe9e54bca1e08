"""Compiled kernels (numba): kinematics, damped least squares, small network calls.

The kernels take arrays and scalars, allocate nothing per joint or per step, write into arrays
the caller owns and release the GIL. Their argument types are declared, so they are compiled
(or loaded from numba's disk cache) when this package is imported, never inside a request; a
call with other types is refused instead of compiled. Where they are cached:
:mod:`sik_ros.kernels._cache`; ``python -m sik_ros.kernels`` compiles them all ahead of use
(``make setup`` and the colcon build do).
"""

import numpy as np

from sik_ros.kernels._cache import CACHE  # noqa: F401 (first: it sets numba's cache folder)


def as_arg(a, dtype=np.float64) -> np.ndarray:
    """``a`` as the kernels take it: C-contiguous, writeable, of ``dtype`` (copied if need be)."""
    a = np.asarray(a, dtype=dtype)
    if not (a.flags.c_contiguous and a.flags.writeable):
        a = np.array(a, dtype=dtype, order='C')
    return a


from sik_ros.kernels.chain import chain_frames, fk_many, jac_many  # noqa: E402,I100
from sik_ros.kernels.dls import refine_rows  # noqa: E402
from sik_ros.kernels.follow import follow_rows  # noqa: E402
from sik_ros.kernels.mlp import mlp_rows, pack_layers  # noqa: E402

__all__ = ['as_arg', 'chain_frames', 'fk_many', 'follow_rows', 'jac_many', 'mlp_rows',
           'pack_layers', 'refine_rows']
