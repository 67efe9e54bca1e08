"""Print the ROS 2 type hash (RIHS01, REP 2011) of every message and service in some packages.

Runs rosidl's own hash generator (``rosidl_generator_type_description``, as a package build
does) on ``.msg``/``.srv`` sources, without building anything: the sources are converted to IDL
(``rosidl_adapter``) in a temporary folder, and the types they use from other packages are read
from those packages' installed ``share/<package>/{msg,srv}/*.json`` descriptions (found on
``AMENT_PREFIX_PATH`` or ``--prefix``), or from a package given earlier on the command line.

Usage (packages in dependency order; ``DIR:FILE,FILE`` takes only those files of ``DIR``)::

    python scripts/type_hashes.py object_recognition_msgs moveit_msgs
    python scripts/type_hashes.py --json out.json upstream/moveit_msgs:msg/RobotState.msg

Each output line is ``<package>/<msg|srv>/<Name> RIHS01_<64 hex digits>``.
"""

import argparse
import contextlib
import io
import json
import os
from pathlib import Path
import sys
import tempfile
from typing import Dict, List, Optional, Sequence, Tuple
import xml.etree.ElementTree as ElementTree

from rosidl_adapter.msg import convert_msg_to_idl
from rosidl_adapter.srv import convert_srv_to_idl
from rosidl_generator_type_description import generate_type_hash


def package_name(directory: Path) -> str:
    """The ``<name>`` of a package's ``package.xml`` (the folder's name without one)."""
    xml = directory / 'package.xml'
    if xml.is_file():
        name = ElementTree.parse(xml).getroot().findtext('name')
        if name:
            return name.strip()
    return directory.name


def sources(directory: Path, only: Optional[Sequence[str]]) -> List[Path]:
    """The ``.msg`` and ``.srv`` files of a package, relative to it (``only``: these)."""
    if only:
        return [Path(f) for f in only]
    return sorted(p.relative_to(directory) for sub in ('msg', 'srv')
                  for p in (directory / sub).glob(f'*.{sub}'))


def installed_includes(prefixes: Sequence[Path]) -> Dict[str, Path]:
    """``share/<package>`` of every package with type descriptions under ``prefixes``."""
    found: Dict[str, Path] = {}
    for prefix in prefixes:
        share = prefix / 'share'
        if not share.is_dir():
            continue
        for pkg in sorted(share.iterdir()):
            if pkg.name not in found and any(pkg.glob('msg/*.json')):
                found[pkg.name] = pkg
    return found


def hash_package(directory: Path, only: Optional[Sequence[str]], includes: Dict[str, Path],
                 work: Path) -> Tuple[str, Path, Dict[str, str]]:
    """Hashes of one package's types: its name, the folder of its descriptions, the hashes."""
    directory = directory.resolve()
    name = package_name(directory)
    idl_dir, out_dir = work / name / 'idl', work / name / 'out'
    tuples = []
    for rel in sources(directory, only):
        target = idl_dir / rel.parent
        target.mkdir(parents=True, exist_ok=True)
        convert = convert_msg_to_idl if rel.suffix == '.msg' else convert_srv_to_idl
        with contextlib.redirect_stdout(io.StringIO()):  # the adapter prints every file
            convert(directory, name, rel, target)
        tuples.append(f'{idl_dir}:{rel.with_suffix(".idl").as_posix()}')
    args = {'package_name': name, 'output_dir': str(out_dir), 'idl_tuples': tuples,
            'include_paths': [f'{pkg}:{path}' for pkg, path in includes.items()
                              if pkg != name]}
    args_file = work / f'{name}.json'
    args_file.write_text(json.dumps(args), encoding='utf-8')
    hashes: Dict[str, str] = {}
    for path in generate_type_hash(str(args_file)):
        described = json.loads(Path(path).read_text(encoding='utf-8'))
        hashes.update({h['type_name']: h['hash_string'] for h in described['type_hashes']
                       if h['type_name'].startswith(name + '/')})
    return name, out_dir, hashes


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Print (and optionally write as JSON) the type hashes of the packages given."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('packages', nargs='+', help='package folders, in dependency order '
                        '(DIR or DIR:FILE,FILE)')
    parser.add_argument('--prefix', action='append', type=Path, default=None,
                        help='install prefix holding the dependencies\' share/ (repeatable; '
                        'default: AMENT_PREFIX_PATH, else this Python\'s prefix)')
    parser.add_argument('--json', type=Path, help='also write {type: hash} to this file')
    args = parser.parse_args(argv)
    prefixes = args.prefix or [Path(p) for p in os.environ.get('AMENT_PREFIX_PATH', '').split(
        os.pathsep) if p] or [Path(sys.prefix)]
    includes = installed_includes(prefixes)
    hashes: Dict[str, str] = {}
    with tempfile.TemporaryDirectory(prefix='type_hashes_') as tmp:
        for spec in args.packages:
            folder, _, files = spec.partition(':')
            if not Path(folder).is_dir():
                print(f'type_hashes: {folder} is not a folder', file=sys.stderr)
                return 2
            name, out_dir, found = hash_package(Path(folder), files.split(',') if files else
                                                None, includes, Path(tmp))
            includes[name] = out_dir
            hashes.update(found)
    for type_name in sorted(hashes):
        print(f'{type_name} {hashes[type_name]}')
    if args.json is not None:
        args.json.write_text(json.dumps(hashes, indent=2, sort_keys=True) + '\n',
                             encoding='utf-8')
    return 0


if __name__ == '__main__':
    sys.exit(main())
