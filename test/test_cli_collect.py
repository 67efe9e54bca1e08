"""sik-collect from the shell: output, and one-line errors with a non-zero exit."""

import signal
import subprocess
import sys
import time

import pytest

pytestmark = pytest.mark.e2e


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
def test_bad_arguments_give_one_line_errors(tmp_path, run_main, args, message):
    """Bad input exits with code 2 and a one-line message naming the problem.

    The first case runs sik-collect as a process (its exit code and stderr as a shell sees
    them, no traceback); the others call its ``main`` here (``run_main``).
    """
    argv = [*args, '--out', str(tmp_path / 'ds'), '--quiet']
    if args == ['--robot', 'nope']:
        r = run(*argv)
        code, err = r.returncode, r.stderr
        assert 'Traceback' not in err
    else:
        from sik_ros.cli.collect import main
        code, err = run_main(main, argv)
    assert code == 2, (code, err)
    assert message in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / 'ds').exists()


def test_existing_output_needs_force(tmp_path):
    """An existing --out is refused without --force."""
    (tmp_path / 'ds').mkdir()
    r = run('--interval', '90', '--out', str(tmp_path / 'ds'), '--quiet')
    assert r.returncode == 2 and '--force' in r.stderr


@pytest.mark.parametrize('sig, code, word', [(signal.SIGTERM, 143, 'SIGTERM'),
                                             (signal.SIGINT, 130, 'SIGINT')])
def test_a_signal_mid_write_leaves_no_partial_files(tmp_path, sig, code, word):
    """SIGTERM or SIGINT while the dataset is written: exit 143/130, one line, nothing left."""
    out = tmp_path / 'ds'
    proc = subprocess.Popen([sys.executable, '-m', 'sik_ros.cli.collect', '--interval', '30',
                             '--out', str(out), '--quiet'], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 90.0
        while time.monotonic() < deadline and proc.poll() is None:
            partial = list(tmp_path.glob('.ds.*.partial'))
            if partial and any(p.stat().st_size for p in partial[0].rglob('*') if p.is_file()):
                break  # writing has begun
            time.sleep(0.05)
        assert proc.poll() is None, 'the collection ended before it could be interrupted'
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == code, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and word in lines[0] and 'removed' in lines[0], err
    assert 'Traceback' not in err
    assert list(tmp_path.iterdir()) == [], list(tmp_path.iterdir())
