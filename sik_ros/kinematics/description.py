"""Robot descriptions given as xacro: expanded to URDF by the ``xacro`` package.

A description is xacro when its file name ends in ``.xacro`` or its text declares the xacro
namespace. :func:`expand_xacro` runs xacro on a file or a text with ``name:=value`` arguments and
turns any xacro failure into one :class:`~sik_ros.errors.InvalidModel` line naming the file and
the problem. :func:`write_xacro_urdf` writes the expansion of a file as a URDF with its
``package://`` meshes resolved to absolute paths, so that the URDF can live apart from the
description package (a bundle's manifest names it).
"""

import os
from pathlib import Path
import re
import threading
from typing import Dict, Mapping, Optional, Sequence, Union
from xml.etree import ElementTree

from sik_ros.errors import InvalidArgument, InvalidModel

XACRO_NAMESPACE = 'http://www.ros.org/wiki/xacro'
#: xacro keeps its file stack and arguments in module globals: one expansion at a time.
_XACRO_LOCK = threading.Lock()


def is_xacro_file(path: Union[str, Path]) -> bool:
    """Whether a description file is xacro (its name ends in ``.xacro``)."""
    return str(path).endswith('.xacro')


def is_xacro_text(text: str) -> bool:
    """Whether a description text is xacro (it declares the xacro namespace)."""
    return XACRO_NAMESPACE in text or 'xmlns:xacro' in text


def parse_xacro_args(items: Sequence[str]) -> Dict[str, str]:
    """``name:=value`` strings as a mapping.

    Raises:
        InvalidArgument: an item without ``:=`` or with an empty name.
    """
    out = {}
    for item in items:
        name, sep, value = item.partition(':=')
        if not sep or not name.strip():
            raise InvalidArgument(f'xacro argument {item!r}: expected name:=value')
        out[name.strip()] = value
    return out


def _one_line(exc: BaseException) -> str:
    """An exception's message on one line."""
    text = re.sub(r'\s+', ' ', str(exc)).strip()
    return text or type(exc).__name__


def expand_xacro(source: Union[Path, str], args: Optional[Mapping[str, str]] = None,
                 name: str = '<robot_description>') -> str:
    """Run xacro on a file (a :class:`~pathlib.Path`) or on a description text.

    Args:
        source: the xacro file, or the text itself (its includes are found from the current
            folder).
        args: xacro arguments (``<xacro:arg>``), name to value.
        name: what to call a text ``source`` in messages.

    Returns:
        the URDF text.

    Raises:
        InvalidModel: ``<file>: <problem>`` on one line, the file being the one (of the
            included ones) where xacro failed.
    """
    import xacro
    label = str(source) if isinstance(source, Path) else name
    if isinstance(source, Path) and not source.is_file():
        raise InvalidModel(f'xacro: {label}: no such file')
    with _XACRO_LOCK:
        try:
            if isinstance(source, Path):
                doc = xacro.process_file(str(source), mappings=dict(args or {}))
            else:
                xacro.init_stacks(None)
                doc = xacro.parse(source)
                xacro.process_doc(doc, mappings=dict(args or {}))
            return doc.toprettyxml(indent='  ')
        # xacro raises its own exception, XML parse errors, I/O errors and whatever a ${...}
        # expression raises: each one is the description's problem, reported as such
        except Exception as exc:
            stack = [f for f in (getattr(xacro, 'filestack', None) or []) if f]
            where = stack[-1] if stack else label
            raise InvalidModel(f'xacro: {where}: {_one_line(exc)}{_macro_note(xacro)}') from exc


def _macro_note(xacro) -> str:
    """Where the macro being instantiated when xacro failed was defined ('' if none was)."""
    macros = getattr(xacro, 'macrostack', None) or []
    if not macros:
        return ''
    macro = macros[-1]
    try:
        defined = macro.history[-1][-1]
    except (AttributeError, IndexError):
        defined = None
    return (f' (in macro {macro.body.getAttribute("name")}'
            f'{f" defined in {defined}" if defined else ""})')


def resolve_package_uris(urdf: str, package_dirs: Sequence[str]) -> str:
    """A URDF's ``package://<pkg>/<path>`` mesh names replaced by the absolute files found.

    A mesh found in none of ``package_dirs`` (folders holding packages) keeps its URI, so that
    loading the URDF names it as missing.
    """
    root = ElementTree.fromstring(urdf)
    changed = False
    for mesh in root.iter('mesh'):
        uri = mesh.get('filename', '')
        if not uri.startswith('package://'):
            continue
        rel = uri[len('package://'):]
        for folder in package_dirs:
            path = Path(folder, rel)
            if path.is_file():
                mesh.set('filename', str(path.resolve()))
                changed = True
                break
    return ElementTree.tostring(root, encoding='unicode') if changed else urdf


def write_xacro_urdf(source: Path, out: Path, args: Optional[Mapping[str, str]] = None,
                     package_dirs: Sequence[str] = ()) -> Path:
    """Expand a xacro file into the URDF file ``out`` (written whole, then renamed onto it).

    Args:
        source: the xacro file.
        out: the URDF file to write.
        args: xacro arguments.
        package_dirs: folders holding the packages its ``package://`` meshes name.

    Raises:
        InvalidModel: xacro failed (one line naming the file and the problem).
    """
    text = resolve_package_uris(expand_xacro(Path(source), args), package_dirs)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f'.{out.name}.tmp{os.getpid()}')
    tmp.write_text(text)
    os.replace(tmp, out)
    return out
