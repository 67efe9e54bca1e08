"""package.xml declares what sik_ros imports, by rosdep key, and pip pins the rest."""

import ast
from pathlib import Path
import re
import sys

from catkin_pkg.package import parse_package

REPO = Path(__file__).resolve().parents[1]
#: Imported module -> its rosdep key, where the two differ.
ROSDEP_KEYS = {
    'numpy': 'python3-numpy',
    'scipy': 'python3-scipy',
    'matplotlib': 'python3-matplotlib',
    'mpl_toolkits': 'python3-matplotlib',
    'tqdm': 'python3-tqdm',
    'yaml': 'python3-yaml',
    'numba': 'python3-numba',
    'llvmlite': 'python3-numba',  # numba's compiler, which it brings along
}
#: Modules without a rosdep key -> the pip distribution pinned in requirements/main.txt.
PIP_ONLY = {
    'torch': 'torch',
    'example_robot_data': 'example-robot-data-loaders',
    'threadpoolctl': 'threadpoolctl',
    'pytracik': 'pytracik',
    'viser': 'viser',
    'trimesh': 'trimesh',
    'ray': 'ray',  # the optional extra sik_ros[ray] (solver/cluster.py)
}


def imported_modules():
    """Top-level names of the modules imported anywhere in sik_ros/, its own excluded."""
    names = set()
    for path in (REPO / 'sik_ros').rglob('*.py'):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names.update(a.name.split('.')[0] for a in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                names.add(node.module.split('.')[0])
    return names - set(sys.stdlib_module_names) - {'sik_ros'}


def test_package_xml_is_valid_and_declares_every_import():
    """Every third-party import is an exec_depend of package.xml or pinned for pip."""
    package = parse_package(str(REPO / 'package.xml'))
    package.validate()
    declared = {d.name for d in package.exec_depends}
    pinned = set(re.findall(r'^([A-Za-z0-9_.\-]+)(?:\[[^\]]*\])?==',
                            (REPO / 'requirements' / 'main.txt').read_text(), re.M))
    missing = []
    for module in sorted(imported_modules()):
        if module in PIP_ONLY:
            if PIP_ONLY[module] not in pinned:
                missing.append(f'{module} (pip: {PIP_ONLY[module]})')
        elif ROSDEP_KEYS.get(module, module) not in declared:
            missing.append(f'{module} (rosdep: {ROSDEP_KEYS.get(module, module)})')
    assert not missing, f'undeclared dependencies: {missing}'


def test_interfaces_package_xml_is_valid():
    """sik_interfaces' manifest parses and validates (colcon skips a package it cannot parse)."""
    package = parse_package(str(REPO / 'sik_interfaces' / 'package.xml'))
    package.validate()
    assert package.get_build_type() == 'ament_cmake'


def test_version_is_written_alike_everywhere():
    """setup.py, package.xml, ``sik_ros.__version__`` and the newest CHANGELOG entry agree."""
    import sik_ros
    package = parse_package(str(REPO / 'package.xml'))
    setup = re.search(r"version='([^']+)'", (REPO / 'setup.py').read_text()).group(1)
    newest = re.search(r'^## ([0-9][^ \n]*)', (REPO / 'CHANGELOG.md').read_text(), re.M).group(1)
    assert package.version == setup == sik_ros.__version__ == newest
