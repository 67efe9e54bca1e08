"""Training from a chain file with rows generated on the device: no Pinocchio on that path."""

import json
import os
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest
import torch

from sik_ros.errors import CorruptArtifact
from sik_ros.kinematics.chain import chain_forward
from sik_ros.kinematics.chain_file import (chain_content, content_sha256, load_chain_file,
                                           write_chain_file)
from sik_ros.learning.checkpoints import load_checkpoint, model_from_checkpoint
from sik_ros.learning.generated_data import GeneratedData
from sik_ros.learning.models import ModelConfig, PRESETS
from sik_ros.learning.provenance import trained_summary
from sik_ros.learning.train_config import TrainConfig
from sik_ros.learning.training import Trainer
from sik_ros.learning.training_data import (default_normalizer, distinct_positions,
                                            TrainData)

ROOT = Path(__file__).resolve().parents[1]
#: What the GPU machine lacks: made unimportable for the processes of the device path.
BLOCKED = ('pinocchio', 'example_robot_data', 'coal', 'rclpy')
#: The largest file the device tool brings back [bytes].
MAX_FILE = 16 * 1024 * 1024


@pytest.fixture
def blocked_env(tmp_path):
    """An environment whose Python cannot import Pinocchio, example-robot-data, coal or rclpy."""
    shim = tmp_path / 'blocked'
    shim.mkdir()
    for name in BLOCKED:
        (shim / f'{name}.py').write_text(f'raise ImportError("{name} is not on this machine")\n')
    path = [str(shim), str(ROOT)] + [p for p in os.environ.get('PYTHONPATH', '').split(
        os.pathsep) if p]
    return dict(os.environ, PYTHONPATH=os.pathsep.join(path))


@pytest.mark.parametrize('name', ['panda', 'ur5'])
def test_a_chain_file_gives_the_robots_kinematics_and_manifest(name, panda, ur5, tmp_path):
    """A robot's chain file reads back to the same FK, limits, names and manifest (any arm)."""
    robot = {'panda': panda, 'ur5': ur5}[name]
    arm = load_chain_file(write_chain_file(robot, tmp_path / f'{name}.json'))
    assert arm.manifest() == robot.manifest() and arm.dof == robot.dof
    assert np.array_equal(arm.lower, robot.lower) and np.array_equal(arm.upper, robot.upper)
    assert np.array_equal(arm.periodic, robot.periodic)
    q = np.random.default_rng(0).uniform(robot.lower, robot.upper, (200, robot.dof))
    p, r = chain_forward(arm.chain, q)
    p_ref, r_ref = robot.fk_rot(q)
    assert np.abs(p - p_ref).max() < 1e-12 and np.abs(r - r_ref).max() < 1e-12
    assert (tmp_path / f'{name}.json').stat().st_size < 10_000


def test_the_shipped_panda_chain_file_is_the_panda_of_today(panda):
    """scripts/device/panda.chain.json (the device recipe's) is the Panda's chain of today."""
    shipped = json.loads((ROOT / 'scripts/device/panda.chain.json').read_text())
    assert {k: v for k, v in shipped.items() if k != 'sha256'} == chain_content(panda)


@pytest.mark.parametrize('damage,message', [
    (lambda c: c['chain']['joint_translations'][0].__setitem__(2, 0.5), 'sha256'),
    (lambda c: c.__setitem__('kind', 'dataset'), 'not a sik_ros chain file'),
    (lambda c: c['robot'].__setitem__('lower', [0.0] * 7), 'lower < upper'),
    (lambda c: c['chain']['joint_rotations'][1][0].__setitem__(0, 2.0), 'not a rotation'),
    (lambda c: c['chain'].__setitem__('axes', [[0, 0, 1]]), 'chain.axes'),
])
def test_a_damaged_chain_file_is_refused(panda, tmp_path, damage, message):
    """An altered, foreign or impossible chain file is a CorruptArtifact naming what is wrong."""
    content = chain_content(panda)
    content['sha256'] = content_sha256(content)
    damage(content)
    if message != 'sha256':  # damage that passes the checksum (written so on purpose)
        content['sha256'] = content_sha256(content)
    path = tmp_path / 'chain.json'
    path.write_text(json.dumps(content))
    with pytest.raises(CorruptArtifact, match=message):
        load_chain_file(path)
    path.write_text(json.dumps(content)[:200])
    with pytest.raises(CorruptArtifact, match='cannot read'):
        load_chain_file(path)


def test_generated_grid_rows_are_sik_collects_grid(panda, grid90, tmp_path):
    """The grid made on the device is sik-collect's Algorithm 1 grid: rows, order, normaliser."""
    # one torch thread, as the training runs here: a sum's order (and its last bits) follows
    # the threads torch splits it over
    torch.set_num_threads(1)
    arm = load_chain_file(write_chain_file(panda, tmp_path / 'panda.json'))
    gen = GeneratedData(arm, 'grid', 90.0)
    assert len(gen) == len(grid90) == gen.manifest['count']
    assert np.array_equal(gen.q.numpy(), np.asarray(grid90.q, dtype=np.float32))
    assert np.abs(gen.position.numpy() - grid90.position).max() < 1e-6
    data = TrainData(grid90, 'pose')
    assert np.abs(gen.rot6.numpy() - data.rot6.numpy()).max() < 1e-6
    a, b = default_normalizer(arm, gen), default_normalizer(panda, grid90)
    assert a.lower == b.lower and a.upper == b.upper
    assert np.allclose(a.position_center, b.position_center, rtol=0, atol=1e-12)
    assert abs(a.position_scale - b.position_scale) < 1e-12
    uni = TrainData(grid90, 'position', uni_position=True)
    rows = distinct_positions(gen.position)
    assert np.abs(gen.position[rows].numpy() - uni.position.numpy()).max() < 1e-6


def test_generated_uniform_rows_are_within_the_limits_and_reach_their_tips(ur5, tmp_path):
    """Uniform rows (a second arm) lie within the limits and their tips are the robot's FK."""
    arm = load_chain_file(write_chain_file(ur5, tmp_path / 'ur5.json'))
    gen = GeneratedData(arm, 'uniform', samples=3000, seed=5)
    q = gen.q.double().numpy()
    assert q.shape == (3000, 6)
    assert np.all(q >= ur5.lower - 1e-6) and np.all(q <= ur5.upper + 1e-6)
    p, _ = ur5.fk_rot(q)
    assert np.abs(p - gen.position.numpy()).max() < 1e-5
    again = GeneratedData(arm, 'uniform', samples=3000, seed=5)
    assert torch.equal(gen.q, again.q)
    assert gen.summary() == {'kind': 'generated', 'sampler': 'uniform',
                             'params': {'samples': 3000, 'seed': 5}, 'count': 3000,
                             'robot': 'ur5', 'urdf_sha256': ur5.urdf_sha256}


def test_a_model_trained_on_generated_rows_records_where_and_resumes(panda, tmp_path):
    """A chain-file run records device, samples and time; a resumed run adds a segment."""
    arm = load_chain_file(write_chain_file(panda, tmp_path / 'panda.json'))
    gen = GeneratedData(arm, 'grid', 90.0)
    cfg = ModelConfig(encoder=PRESETS['tiny'][0], decoder=PRESETS['tiny'][1])
    tc = TrainConfig(steps=6, batch_size=128, warmup=1, eval_every=3, checkpoint_every=3,
                     val_rows=300, sampler='uniform')
    first = Trainer(arm, gen, cfg, tc, tmp_path / 'run')

    def stop(step, rec):
        if step == 4:
            raise KeyboardInterrupt  # as Ctrl-C or SIGTERM stop sik-train
    with pytest.raises(KeyboardInterrupt):
        first.run(progress=stop)
    ckpt = load_checkpoint(tmp_path / 'run' / 'last.pt')
    assert ckpt['robot'] == panda.manifest() and ckpt['dataset'] == gen.summary()
    again = Trainer(arm, GeneratedData(arm, 'grid', 90.0), cfg, tc, tmp_path / 'run')
    again.restore(ckpt)
    again.run()
    rec = load_checkpoint(tmp_path / 'run' / 'last.pt')['trained']
    assert [s['steps'] for s in rec['segments']] == [4, 2]
    assert rec['samples'] == 6 * 128 and rec['steps'] == 6
    assert rec['devices'][0].startswith('cpu: ')
    summary = trained_summary(load_checkpoint(tmp_path / 'run' / 'last.pt'))
    assert summary['recorded'] and summary['total_samples'] == 6 * 128


def test_a_checkpoint_without_a_record_is_summarised_from_its_steps():
    """The shipped Panda pose model (no record) reads as steps x batch, device not recorded."""
    ckpt = load_checkpoint(ROOT / 'sik_ros/bundles/panda/sik_pose.pt')
    summary = trained_summary(ckpt)
    assert not summary['recorded'] and summary['devices'] == ['not recorded']
    assert summary['samples'] == ckpt['step'] * ckpt['train_config']['batch_size']


@pytest.mark.e2e
def test_the_device_path_imports_no_pinocchio(blocked_env):
    """sik-train --chain's modules import with Pinocchio, example-robot-data and rclpy absent."""
    code = ('import sys; import sik_ros.cli.train as t; import sik_ros.learning.training; '
            'import sik_ros.learning.generated_data; import sik_ros.kinematics.chain_file; '
            'bad = [m for m in ("pinocchio", "example_robot_data", "rclpy") '
            'if sys.modules.get(m) is not None]; print(bad)')
    run = subprocess.run([sys.executable, '-c', code], env=blocked_env, capture_output=True,
                         text=True, timeout=120, cwd=ROOT)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.strip() == '[]'


@pytest.mark.e2e
def test_the_device_recipe_runs_end_to_end_without_pinocchio(panda, blocked_env, tmp_path):
    """scripts/device_train.py (tiny, CPU) trains the Panda models, resumes, brings them back."""
    out, runs = tmp_path / 'out', tmp_path / 'runs'
    # --budget 1: a second of training per run instead of the tiny recipe's 3 (the path is what
    # is tested; a run trains one step at least, however short its budget)
    cmd = [sys.executable, str(ROOT / 'scripts/device_train.py'), '--group', 'sik',
           '--device', 'cpu', '--tiny', '--budget', '1', '--out', str(out), '--runs', str(runs)]
    run = subprocess.run(cmd, env=blocked_env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    files = sorted(p.name for p in out.iterdir())
    assert files == ['log.txt', 'sik_pose.pt', 'sik_position.pt', 'summary.json']
    summary = json.loads((out / 'summary.json').read_text())
    steps = {}
    for s in summary['runs']:
        path = out / f'{s["name"]}.pt'
        assert path.stat().st_size < MAX_FILE  # with its optimiser state: resumable
        ckpt = load_checkpoint(path)
        model, cfg, _ = model_from_checkpoint(ckpt)
        assert ckpt['robot'] == panda.manifest() and cfg.latent_dim == 4
        assert ckpt['trained']['init']['file'] == f'{s["name"]}.pt'
        assert s['trained']['samples'] == ckpt['step'] * 256 > 0
        steps[s['name']] = ckpt['step']
    # the same command again resumes each run from its folder (a warm machine's second call)
    again = subprocess.run(cmd, env=blocked_env, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stdout[-2000:] + again.stderr[-2000:]
    for s in json.loads((out / 'summary.json').read_text())['runs']:
        assert '--resume' in s['command'] and s['step'] >= steps[s['name']]


def test_sik_chain_and_sik_train_refuse_bad_input(run_main, tmp_path):
    """Bad chain-file input is one line and exit 2 from sik-chain and sik-train."""
    from sik_ros.cli.chain import main as chain_main
    from sik_ros.cli.train import main as train_main
    code, err = run_main(chain_main, ['--bundle', str(tmp_path / 'nothing'), '--out',
                                      str(tmp_path / 'c.json')])
    assert code == 2 and 'no bundle' in err and len(err.strip().splitlines()) == 1
    bad = tmp_path / 'bad.json'
    bad.write_text('{"kind": "sik_chain"}')
    for argv, message in [
            (['--chain', str(bad)], 'format version'),
            (['--chain', str(bad), '--max-time', '5', '--fit-schedule', '--resume'],
             'does not exist'),
            (['--chain', str(bad), '--fit-schedule'], '--fit-schedule'),
            (['--chain', str(bad), '--dataset', str(tmp_path)], 'not allowed with')]:
        code, err = run_main(train_main, argv + ['--out', str(tmp_path / 'run'), '--quiet'])
        assert code == 2 and message in err, (argv, err)


def test_sik_build_on_a_gpu_refuses_at_once_where_there_is_none(run_main, tmp_path):
    """sik-build --device cuda without a CUDA device is one line, exit 2, nothing written."""
    if torch.cuda.is_available():
        pytest.skip('this machine has a CUDA device')
    from sik_ros.cli.build import main
    out = tmp_path / 'ur5'
    code, err = run_main(main, ['--robot', 'ur5', '--out', str(out), '--device', 'cuda',
                                '--quiet'])
    assert code == 2 and 'no CUDA device' in err and len(err.strip().splitlines()) == 1
    assert not out.exists() and not (tmp_path / 'ur5.build').exists()


def test_a_bundle_records_where_and_on_how_many_samples_its_models_trained(tiny_bundle):
    """bundle.json keeps each model's training summary, and sik-eval's model line shows it."""
    from sik_ros.eval.histories import bundle_histories
    from sik_ros.eval.report import model_line
    from sik_ros.solver import SelectiveIK
    manifest = json.loads((Path(tiny_bundle) / 'bundle.json').read_text())
    for goal in ('position', 'pose'):
        rec = manifest['trained'][goal]
        assert rec['recorded'] and rec['samples'] == rec['steps'] * 512 > 0
        assert rec['devices'][0].startswith('cpu: ')
    h = bundle_histories(SelectiveIK.load(tiny_bundle))['position']
    assert f'{h.trained["samples"]:,} samples' in model_line('position', h, {})
