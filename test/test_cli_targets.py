"""sik-solve --targets: a file of targets, ranked answers of each, an NPZ, exit 2 on a bad file."""

import json
import subprocess
import sys

import numpy as np
import pytest

from sik_ros.cli import solve
from sik_ros.solver import SelectiveIK

pytestmark = pytest.mark.e2e  # runs the command as a process too


def test_targets_file_answers_every_row_into_an_npz(tiny_bundle, tmp_path, run_main):
    """Each CSV row's answer lands in the NPZ in row order, its solutions those of solve."""
    ik = SelectiveIK.load(tiny_bundle)
    q = np.random.default_rng(3).uniform(ik.robot.lower, ik.robot.upper, (6, ik.robot.dof))
    rows = np.array([np.concatenate(ik.fk(qi)) for qi in q])
    np.savetxt(tmp_path / 't.csv', rows, delimiter=',')
    out = tmp_path / 'answers.npz'
    code, _ = run_main(solve.main, ['--targets', str(tmp_path / 't.csv'), '--bundle',
                                    str(tiny_bundle), '-n', '4', '--out', str(out),
                                    '--workers', '1'])
    assert code in (0, 1)
    data = np.load(out)
    assert json.loads(str(data['manifest']))['targets'] == 6
    assert data['q'].shape[:1] == (6,) and data['q'].shape[2] == ik.robot.dof
    for i, row in enumerate(rows):
        res = ik.solve(row[:3], row[3:], num_solutions=4)
        assert data['count'][i] == len(res.solutions)
        assert bool(data['success'][i]) == res.success
        for j, s in enumerate(res.solutions):
            assert np.allclose(data['q'][i, j], s.q, atol=1e-9)


def test_a_bad_targets_file_is_one_line_and_exit_2(tmp_path):
    """Rows of 4 numbers, as a shell sees it: exit 2, one line, no traceback, no bundle."""
    bad = tmp_path / 'bad.csv'
    bad.write_text('0.4 0.1 0.5 1\n')
    run = subprocess.run([sys.executable, '-m', 'sik_ros.cli.solve', '--targets', str(bad)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2
    assert len(run.stderr.strip().splitlines()) == 1 and 'Traceback' not in run.stderr
    assert '3 (x y z) or 7' in run.stderr
