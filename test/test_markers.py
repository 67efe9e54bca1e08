"""The marker lists of conftest.py name modules and tests that exist."""

import ast
from pathlib import Path

import conftest

TESTS = Path(__file__).resolve().parent


def _test_names(module: str) -> set:
    tree = ast.parse((TESTS / f'{module}.py').read_text())
    return {n.name for n in tree.body if isinstance(n, ast.FunctionDef)
            and n.name.startswith('test_')}


def test_marker_lists_name_existing_tests():
    """Every module and ``module::test`` in the e2e and slow lists exists (no stale name)."""
    for module in conftest.E2E_MODULES | conftest.SLOW_MODULES:
        assert (TESTS / f'{module}.py').is_file(), module
    for entry in conftest.E2E_TESTS | conftest.SLOW_TESTS:
        module, name = entry.split('::')
        assert name in _test_names(module), entry
