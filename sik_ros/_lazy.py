"""Public names loaded on first use (PEP 562), for a package's ``__init__``.

A package lists where each public name lives; :func:`lazy_exports` gives it the module-level
``__getattr__`` and ``__dir__`` that import the module only when the name is first used, so that
importing a light module of the package (``sik_ros.errors``, a CLI's ``--help``) does not load
torch or Pinocchio.
"""

from importlib import import_module
from typing import Any, Callable, Dict, List, Tuple


def lazy_exports(package: str, namespace: Dict[str, Any], exports: Dict[str, str]
                 ) -> Tuple[Callable[[str], Any], Callable[[], List[str]]]:
    """``__getattr__`` and ``__dir__`` for ``package``, whose globals are ``namespace``.

    Args:
        package: the package's ``__name__``.
        namespace: its ``globals()``; a name, once loaded, is kept there.
        exports: public name -> the module that defines it.
    """
    def __getattr__(name: str) -> Any:
        """Load a public name from its module on first use."""
        module = exports.get(name)
        if module is None:
            raise AttributeError(f'module {package!r} has no attribute {name!r}')
        value = getattr(import_module(module), name)
        namespace[name] = value
        return value

    def __dir__() -> List[str]:
        """The package's names, the lazy public ones included."""
        return sorted(set(namespace) | set(exports))

    return __getattr__, __dir__
