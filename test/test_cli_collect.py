"""sik-collect from the shell: output, and one-line errors with a non-zero exit."""

import subprocess
import sys

import pytest


def run(*args):
    """Run sik-collect as a subprocess."""
    return subprocess.run([sys.executable, '-m', 'sik_ros.cli.collect', *args],
                          capture_output=True, text=True, timeout=120)


def test_collect_writes_dataset(tmp_path):
    """sik-collect writes a dataset and says how many rows."""
    r = run('--interval', '90', '--out', str(tmp_path / 'ds'), '--quiet')
    assert r.returncode == 0, r.stderr
    assert 'wrote 4608 rows' in r.stdout
    assert (tmp_path / 'ds' / 'manifest.json').is_file()


@pytest.mark.parametrize('args,message', [
    (['--robot', 'nope'], 'available:'),
    (['--interval', '0'], 'interval'),
    (['--interval', '500'], 'larger than the range'),
    (['--sampler', 'uniform', '--samples', '0'], '--samples'),
    (['--urdf', '/no/such.urdf', '--base', 'a', '--tip', 'b'], 'not found'),
])
def test_bad_arguments_give_one_line_errors(tmp_path, args, message):
    """Bad input exits with code 2 and a one-line message naming the problem."""
    r = run(*args, '--out', str(tmp_path / 'ds'), '--quiet')
    assert r.returncode == 2
    assert message in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / 'ds').exists()


def test_existing_output_needs_force(tmp_path):
    """An existing --out is refused without --force."""
    (tmp_path / 'ds').mkdir()
    r = run('--interval', '90', '--out', str(tmp_path / 'ds'), '--quiet')
    assert r.returncode == 2 and '--force' in r.stderr
