"""Tests that start a process say so: they carry the ``e2e`` marker themselves."""

import ast
from pathlib import Path

TESTS = Path(__file__).resolve().parent
#: Calls that start a process: a node, a command-line tool, a build.
STARTS = ('subprocess.run', 'subprocess.Popen', 'subprocess.check_output', 'launch_node')


def _marks(decorators) -> set:
    """Names of the pytest marks among decorators or a ``pytestmark`` value."""
    names = set()
    for node in decorators:
        for sub in ast.walk(node):
            if isinstance(sub, ast.Attribute) and isinstance(sub.value, ast.Attribute) \
                    and sub.value.attr == 'mark':
                names.add(sub.attr)
    return names


def _starts_a_process(func: ast.FunctionDef) -> bool:
    return any(ast.unparse(n.func).endswith(STARTS) for n in ast.walk(func)
               if isinstance(n, ast.Call))


def test_every_test_that_starts_a_process_is_marked_e2e():
    """A test function calling subprocess or launching a node is ``e2e`` (module or decorator)."""
    unmarked = []
    for path in sorted(TESTS.glob('test_*.py')):
        tree = ast.parse(path.read_text())
        module_marks = set()
        for node in tree.body:
            if isinstance(node, ast.Assign) and any(
                    isinstance(t, ast.Name) and t.id == 'pytestmark' for t in node.targets):
                module_marks |= _marks([node.value])
        for node in tree.body:
            if isinstance(node, ast.FunctionDef) and node.name.startswith('test_') \
                    and _starts_a_process(node) \
                    and 'e2e' not in module_marks | _marks(node.decorator_list):
                unmarked.append(f'{path.stem}::{node.name}')
    assert not unmarked, unmarked
