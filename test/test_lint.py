"""Lint like ROS does: flake8 at 99 columns with Google import order, and pep257 docstrings."""

from pathlib import Path
import subprocess
import sys

import pytest

pytestmark = pytest.mark.e2e

REPO = Path(__file__).resolve().parents[1]
LINTED = [name for name in ('sik_ros', 'test', 'bench', 'setup.py') if (REPO / name).exists()]

# ament_pep257's default ignore list.
# D401 (imperative mood) is also off: properties and attribute-like functions read better
# as nouns ("Number of joints.").
PEP257_IGNORE = 'D100,D101,D102,D103,D104,D105,D106,D107,D203,D212,D401,D404'


def _run(args):
    return subprocess.run(
        [sys.executable, '-m', *args], cwd=REPO, capture_output=True, text=True, timeout=300)


def test_flake8():
    """Flake8 with the repo's setup.cfg (99 columns, Google import order) finds nothing."""
    result = _run(['flake8', '--config', 'setup.cfg', *LINTED])
    findings = [line for line in result.stdout.splitlines() if line.strip()]
    print('\n'.join(findings))
    print(result.stderr, file=sys.stderr)
    assert result.returncode == 0 and not findings, (
        f'{len(findings)} flake8 finding(s):\n' + '\n'.join(findings) + result.stderr)


def test_pep257():
    """Docstrings pass pydocstyle with ament_pep257's defaults (pep257 convention)."""
    result = _run([
        'pydocstyle', '--convention=pep257', f'--add-ignore={PEP257_IGNORE}',
        '--match=(?!\\.).*\\.py', *LINTED])
    findings = [line for line in result.stdout.splitlines() if line.strip()]
    print('\n'.join(findings))
    print(result.stderr, file=sys.stderr)
    assert result.returncode == 0 and not findings, (
        f'{len(findings) // 2} pydocstyle finding(s):\n' + '\n'.join(findings) + result.stderr)
