"""``python -m sik_ros.kernels``: compile every kernel into numba's disk cache, ahead of use.

Each kernel module declares its kernels' argument types, so importing it compiles them (or
loads them from the cache; the package's own modules are compiled as it is imported, before
this runs). ``make setup`` and the colcon build run this once, so that the first solve after a
set-up does not wait for the compiler.
"""

import importlib
import pkgutil
import sys
from typing import List, Optional


def main(argv: Optional[List[str]] = None) -> int:
    """Import (so compile) every module of :mod:`sik_ros.kernels`; 1 if they are not cached."""
    del argv
    import sik_ros.kernels as kernels
    names = [m.name for m in pkgutil.iter_modules(kernels.__path__) if not m.name.startswith('_')]
    for name in names:
        importlib.import_module(f'sik_ros.kernels.{name}')
    where = 'cached on disk' if kernels.CACHE else 'NOT cached (no private cache folder)'
    print(f'sik_ros kernels: {len(names)} modules compiled, {where}')
    return 0 if kernels.CACHE else 1


if __name__ == '__main__':
    sys.exit(main())
