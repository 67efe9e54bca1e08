"""Compiled kernels (numba): kinematics, damped least squares, small network calls.

The kernels take arrays and scalars, allocate nothing per joint or per step, write into arrays
the caller owns and release the GIL. Their argument types are declared, so they are compiled
(or loaded from numba's disk cache) when this package is imported, never inside a request; a
call with other types is refused instead of compiled. The cache lives in ``__pycache__`` beside
the sources, or in numba's user cache directory (``NUMBA_CACHE_DIR``, else
``~/.cache/numba``) when the package's folder is read-only.
"""

from sik_ros.kernels.chain import chain_frames, fk_many, jac_many
from sik_ros.kernels.dls import follow_rows, refine_rows
from sik_ros.kernels.mlp import mlp_rows, pack_layers

__all__ = ['chain_frames', 'fk_many', 'follow_rows', 'jac_many', 'mlp_rows', 'pack_layers',
           'refine_rows']
