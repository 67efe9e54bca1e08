"""Bad input at the library's edge: every malformed value is a SikError naming the field."""

import math

import numpy as np
import pytest

from sik_ros import InvalidArgument, InvalidGoal, Obstacle, SelectiveIK, SikError


@pytest.fixture(scope='module')
def ik():
    """The bundled Panda solver."""
    return SelectiveIK.load('panda')


GOAL = (0.4, -0.2, 0.4)


@pytest.mark.parametrize('kwargs, error, words', [
    ({'position': (1e300, 0, 0)}, InvalidGoal, 'position must lie within 100 m'),
    ({'position': (1e155, 0, 0)}, InvalidGoal, 'position must lie within 100 m'),
    ({'position': ('a', 0, 0)}, InvalidGoal, 'position must be 3 numbers'),
    ({'orientation': (0, 0, 0, 0)}, InvalidGoal, 'quaternion is zero'),
    ({'orientation': (1e-200, 0, 0, 0)}, InvalidGoal, 'quaternion is zero'),
    ({'timeout': '1'}, InvalidArgument, 'timeout must be a number'),
    ({'timeout': -1.0}, InvalidArgument, 'timeout must be finite and >= 0'),
    ({'timeout': math.nan}, InvalidArgument, 'timeout must be finite and >= 0'),
    ({'obstacles': None}, InvalidArgument, 'obstacles must be a list'),
    ({'obstacles': 'box'}, InvalidArgument, 'obstacles must be a list'),
    ({'obstacles': ({'shape': 'box', 'dims': (1, 1, 1)},)}, InvalidArgument, "keys ['dims'"),
    ({'obstacles': [Obstacle('sphere', (0.1,))] * 257}, InvalidArgument, 'at most 256'),
    ({'objective': 5}, InvalidArgument, 'objective must be an Objective'),
    ({'refine': 'yes'}, InvalidArgument, 'refine must be True or False'),
    ({'num_solutions': 2.5}, InvalidArgument, 'num_solutions must be an integer'),
])
def test_bad_options_raise_a_sik_error_naming_the_field(ik, kwargs, error, words):
    """Each malformed option is refused before any work, with the field in the message."""
    args = {'position': GOAL, **kwargs}
    with pytest.raises(error, match=words.replace('[', r'\[').replace('(', r'\(')):
        ik.solve(**args)


def test_huge_quaternions_are_normalised_safely(ik):
    """(1e200, 0, 0, 1e200) is the 90 degree turn about x it stands for, not an overflow."""
    p, _ = ik.fk(np.zeros(7))
    res = ik.solve(p, orientation=(1e200, 0, 0, 1e200), num_solutions=2)
    assert res.solutions and all(np.isfinite(s.orientation_error) for s in res.solutions)


@pytest.mark.parametrize('make, words', [
    (lambda ik: Obstacle('box', ('a', 'b', 'c')), 'box obstacle needs 3 positive'),
    (lambda ik: Obstacle('box', (1, 1, 1), position=(1e300, 0, 0)), 'within 100 m'),
    (lambda ik: Obstacle('box', (1, 1, 1), quaternion=(0, 0, 0, 0)), 'quaternion is zero'),
    (lambda ik: Obstacle(5, (1, 1, 1)), 'shape must be box'),
    (lambda ik: ik.fk([math.nan] * 7), 'q must be finite'),
    (lambda ik: ik.fk([0.0] * 6), 'q must have 7 elements'),
    (lambda ik: ik.with_config(prune_at=5), 'prune_at must hold integers'),
    (lambda ik: SelectiveIK.load(None), 'bundle must be'),
    (lambda ik: ik.solve_batch('abc'), 'positions must'),
])
def test_bad_values_elsewhere_raise_sik_errors(ik, make, words):
    """Obstacles, fk, settings, loading and batches refuse bad values with a SikError."""
    with pytest.raises(SikError, match=words):
        make(ik)


def _junk(rng):
    """A random malformed (or sometimes valid) value of a random kind."""
    pick = rng.integers(10)
    if pick == 0:
        return None
    if pick == 1:
        return 'x' * int(rng.integers(4))
    if pick == 2:
        return float(rng.choice([math.nan, math.inf, -math.inf, 1e308, -1e-320, 0.0]))
    if pick == 3:
        return {'shape': 'box'}
    if pick == 4:
        return [float(v) for v in rng.normal(0, 10.0 ** rng.integers(-3, 300), rng.integers(6))]
    if pick == 5:
        return tuple(rng.uniform(-0.8, 0.8, 3))
    if pick == 6:
        return [[1, 2], [3]]
    if pick == 7:
        return int(rng.integers(-5, 100))
    if pick == 8:
        return np.full(int(rng.integers(1, 8)), rng.choice([math.nan, 1.0, 1e200]))
    return bool(rng.integers(2))


def test_fuzzed_solve_arguments_give_a_sik_error_or_a_valid_result(ik):
    """500 seeded random argument sets: only SikError or a result whose errors are honest."""
    rng = np.random.default_rng(13)
    results = errors = 0
    for _ in range(500):
        kwargs = {'position': _junk(rng) if rng.random() < 0.7 else tuple(rng.uniform(-.6, .6, 3))}
        for name in ('orientation', 'num_solutions', 'seed', 'obstacles', 'refine', 'timeout',
                     'objective'):
            if rng.random() < 0.3:
                kwargs[name] = _junk(rng)
        try:
            res = ik.solve(**kwargs)
        except SikError:
            errors += 1
            continue
        results += 1
        for s in res.solutions:
            p, _ = ik.fk(s.q)
            assert abs(np.linalg.norm(p - np.asarray(kwargs['position'])) - s.position_error) \
                < 1e-9
            assert np.all(s.q >= ik.robot.lower - 1e-9) and np.all(s.q <= ik.robot.upper + 1e-9)
    assert results > 20 and errors > 200, (results, errors)


# -- command lines ------------------------------------------------------------------------------

def _cli(*args, timeout=120):
    import subprocess
    import sys
    return subprocess.run([sys.executable, '-m', *args], capture_output=True, text=True,
                          timeout=timeout)


@pytest.mark.parametrize('args', [(), ('0.4', '0.1'), ('0.4', '0', 'x'), ('1e300', '0', '0.4'),
                                  ('0.4', '0', '0.4', '--orientation', '0', '0', '0', '0')])
def test_sik_solve_usage_and_input_errors_are_one_line_and_exit_2(args, run_main):
    """Missing or bad arguments: exit 2, one line on stderr, no traceback."""
    from sik_ros.cli.solve import main
    code, err = run_main(main, args)
    assert code == 2, (code, err)
    assert len(err.strip().splitlines()) == 1 and 'Traceback' not in err


@pytest.mark.e2e
def test_sik_solve_exits_non_zero_when_it_prints_failed():
    """An unreachable target prints FAILED and exits 1."""
    run = _cli('sik_ros.cli.solve', '3', '0', '0.4', '-n', '2')
    assert run.returncode == 1 and run.stdout.startswith('FAILED'), run.stdout


def test_sik_solve_heads_its_table_with_the_words_that_tell_joints_apart():
    """UR-style names lose their shared ``_joint``; names that would clash are kept whole."""
    from sik_ros.cli.solve import short_names
    ur = ['shoulder_pan_joint', 'shoulder_lift_joint', 'elbow_joint', 'wrist_1_joint']
    assert short_names(ur) == ['shoulder_pan', 'shoulder_lift', 'elbow', 'wrist_1']
    assert short_names([f'panda_joint{i}' for i in (1, 2)]) == ['joint1', 'joint2']
    assert short_names(['arm_a_joint', 'arm_a_joint']) == ['arm_a_joint', 'arm_a_joint']


def _dataset(tmp_path, panda, **manifest_changes):
    """A tiny valid dataset, then its manifest or arrays changed."""
    import json
    from sik_ros.tables.dataset import collect
    ds = collect(panda, tmp_path / 'ds', sampler='uniform', samples=50, seed=1)
    m = json.loads((ds.path / 'manifest.json').read_text())
    for key, value in manifest_changes.items():
        if value is None:
            m.pop(key)
        else:
            m[key] = value
    (ds.path / 'manifest.json').write_text(json.dumps(m))
    return ds.path


@pytest.mark.parametrize('change, words', [
    ({'count': None}, 'row count'),
    ({'count': 0}, 'row count'),
    ({'robot': ['panda']}, 'robot manifest'),
])
@pytest.mark.e2e
def test_malformed_dataset_manifests_are_one_line_errors(tmp_path, panda, run_main, change,
                                                         words):
    """sik-train on a dataset whose manifest lacks or garbles its count or robot: one line.

    The first case runs sik-train as a process (its exit code and stderr as a shell sees
    them, no traceback); the others call its ``main`` here.
    """
    from sik_ros.cli.train import main
    path = _dataset(tmp_path, panda, **change)
    argv = ['--dataset', str(path), '--out', str(tmp_path / 'run'), '--steps', '1', '--quiet']
    if change == {'count': None}:
        run = _cli('sik_ros.cli.train', *argv)
        code, err = run.returncode, run.stderr
        assert 'Traceback' not in err
    else:
        code, err = run_main(main, argv)
    assert code == 2 and words in err, err
    assert len(err.strip().splitlines()) == 1


def test_dataset_arrays_of_the_wrong_type_or_not_finite_are_refused(tmp_path, panda):
    """q.npy stored as int8, or NaN positions: CorruptArtifact naming the file."""
    from sik_ros.errors import CorruptArtifact
    from sik_ros.tables.dataset import Dataset
    path = _dataset(tmp_path, panda)
    q = np.load(path / 'q.npy')
    np.save(path / 'q.npy', q.astype(np.int8))
    with pytest.raises(CorruptArtifact, match='q.npy holds int8'):
        Dataset.load(path)
    np.save(path / 'q.npy', q)
    pos = np.load(path / 'position.npy')
    pos[3, 1] = np.nan
    np.save(path / 'position.npy', pos)
    with pytest.raises(CorruptArtifact, match='position.npy has non-finite'):
        Dataset.load(path)


def test_a_goal_quaternion_becomes_the_rotation_scipy_gives():
    """The goal's rotation matrix, made in Python floats, is scipy's to the last bit."""
    from scipy.spatial.transform import Rotation
    from sik_ros.kinematics.rotations import quaternion_matrix
    from sik_ros.validation import quaternion
    rng = np.random.default_rng(4)
    for raw in rng.normal(size=(200, 4)) * 10.0 ** rng.uniform(-3, 3, (200, 1)):
        quat = quaternion(raw, 'orientation')
        np.testing.assert_array_equal(quaternion_matrix(quat),
                                      Rotation.from_quat(quat).as_matrix())


def test_waypoint_quaternions_become_scipys_rotations_and_back():
    """A path's rotations are scipy's to the last bit, and a matrix's quaternion to 1e-15.

    The quaternion of one matrix (either sign) has w >= 0, at the half turns too.
    """
    from scipy.spatial.transform import Rotation
    from sik_ros.kinematics.rotations import matrix_quaternion
    from sik_ros.solver.inputs import check_path
    rng = np.random.default_rng(5)
    raw = rng.normal(size=(300, 4)) * 10.0 ** rng.uniform(-3, 3, (300, 1))
    goals = check_path(np.zeros((300, 3)), raw, ('pose',))
    unit = np.array([g.given_quaternion for g in goals])
    np.testing.assert_array_equal(np.array([g.rotation for g in goals]),
                                  Rotation.from_quat(unit).as_matrix())
    rots = np.concatenate([Rotation.from_quat(unit).as_matrix(), np.eye(3)[None],
                           np.diag([1.0, -1.0, -1.0])[None], np.diag([-1.0, 1.0, -1.0])[None],
                           np.diag([-1.0, -1.0, 1.0])[None]])
    ours = np.array([matrix_quaternion(r) for r in rots])
    theirs = Rotation.from_matrix(rots).as_quat()
    assert np.all(ours[:, 3] >= 0)
    assert np.minimum(np.abs(ours - theirs).max(axis=1),
                      np.abs(ours + theirs).max(axis=1)).max() < 1e-15


def test_a_distinct_threshold_of_a_whole_turn_or_more_is_refused(ik):
    """2 pi equivalents are told apart by a whole turn of a joint: the threshold stays below."""
    with pytest.raises(InvalidArgument, match='distinct_threshold must be below 2 pi'):
        ik.with_config(distinct_threshold=2 * math.pi)
    assert ik.with_config(distinct_threshold=6.0).config.distinct_threshold == 6.0
