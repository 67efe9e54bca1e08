"""Training: a real drop in FK error, determinism, checkpoints, resume, refusal of bad files."""

import subprocess
import sys

import numpy as np
import pinocchio as pin
import pytest
from served import check_served
import torch

from sik_ros.errors import ArtifactMismatch, CorruptArtifact, TrainingDiverged
from sik_ros.kinematics.robot import find_frame
from sik_ros.learning.checkpoints import export_model, load_checkpoint, model_from_checkpoint
from sik_ros.learning.models import ModelConfig, PRESETS
from sik_ros.learning.train_config import TrainConfig
from sik_ros.learning.training import Trainer

pytestmark = pytest.mark.slow

TINY = ModelConfig(encoder=PRESETS['tiny'][0], decoder=PRESETS['tiny'][1])


def trainer(panda, ds, out, model=TINY, **kw):
    """A trainer with a tiny, fast config."""
    cfg = TrainConfig(**{'steps': 60, 'batch_size': 256, 'lr': 3e-3, 'warmup': 5,
                         'eval_every': 30, 'checkpoint_every': 30, 'val_rows': 500,
                         'threads': 1, **kw})
    return Trainer(panda, ds, model, cfg, out)


def test_training_lowers_fk_distance_error(panda, uniform_small, tmp_path):
    """A short run on a small dataset lowers the validation FK distance error clearly."""
    t = trainer(panda, uniform_small, tmp_path, steps=300, eval_every=300)
    before = t.validate()['val_dist_mean_m']
    after = t.run()['val_dist_mean_m']
    assert after < 0.6 * before, (before, after)


def test_training_is_deterministic(panda, uniform_small, tmp_path):
    """Two runs with the same seed on the CPU give identical weights."""
    a = trainer(panda, uniform_small, tmp_path / 'a', steps=20)
    b = trainer(panda, uniform_small, tmp_path / 'b', steps=20)
    a.run()
    b.run()
    for k, v in a.model.state_dict().items():
        assert torch.equal(v, b.model.state_dict()[k]), k


def test_resume_continues_exactly(panda, uniform_small, tmp_path):
    """Stopping after 30 steps and resuming gives the same weights as 60 steps in one go."""
    whole = trainer(panda, uniform_small, tmp_path / 'whole')
    whole.run()
    first = trainer(panda, uniform_small, tmp_path / 'parts', steps=60)
    first.run(max_time=0.0)  # stops after its first step and checkpoints
    ckpt = load_checkpoint(tmp_path / 'parts' / 'last.pt')
    assert ckpt['step'] == 1
    second = trainer(panda, uniform_small, tmp_path / 'parts')
    second.restore(ckpt)
    second.run()
    assert second.step == 60
    for k, v in whole.model.state_dict().items():
        assert torch.equal(v, second.model.state_dict()[k]), k


def test_checkpoint_reloads_bit_for_bit(panda, uniform_small, tmp_path):
    """An exported model rebuilds the same module, weight for weight."""
    t = trainer(panda, uniform_small, tmp_path, steps=10)
    t.run()
    export_model(t.checkpoint(), tmp_path / 'model.pt')
    model, cfg, norm = model_from_checkpoint(load_checkpoint(tmp_path / 'model.pt'))
    assert cfg == TINY
    for k, v in t.model.state_dict().items():
        assert torch.equal(v, model.state_dict()[k])


def test_corrupt_checkpoint_is_refused(panda, uniform_small, tmp_path):
    """A truncated checkpoint file is refused with CorruptArtifact."""
    t = trainer(panda, uniform_small, tmp_path, steps=5)
    t.run()
    path = tmp_path / 'last.pt'
    path.write_bytes(path.read_bytes()[:1000])
    with pytest.raises(CorruptArtifact):
        load_checkpoint(path)


def test_mismatched_checkpoint_is_refused(panda, uniform_small, grid90, tmp_path):
    """Resuming with another dataset or another model config is refused."""
    t = trainer(panda, uniform_small, tmp_path, steps=5)
    t.run()
    ckpt = load_checkpoint(tmp_path / 'last.pt')
    with pytest.raises(ArtifactMismatch, match='dataset'):
        trainer(panda, grid90, tmp_path / 'x').restore(ckpt)
    other = ModelConfig(encoder=PRESETS['tiny'][0], decoder=PRESETS['tiny'][1], latent_dim=2)
    with pytest.raises(ArtifactMismatch, match='model config'):
        trainer(panda, uniform_small, tmp_path / 'y', model=other).restore(ckpt)


def test_nan_loss_stops_with_clear_error(panda, uniform_small, tmp_path):
    """A loss that becomes NaN stops the run with TrainingDiverged, keeping the checkpoint."""
    t = trainer(panda, uniform_small, tmp_path, steps=40, checkpoint_every=10)
    t.run(max_time=0.0)
    good = (tmp_path / 'last.pt').read_bytes()
    with torch.no_grad():
        next(t.model.parameters()).fill_(float('nan'))
    with pytest.raises(TrainingDiverged, match='last good checkpoint'):
        t.run()
    assert (tmp_path / 'last.pt').read_bytes() == good


def test_psik_fcn_and_anfis_train(panda, uniform_small, tmp_path):
    """PSIK (with KL), the FCN and ANFIS (particle swarm) each take their 10 steps.

    Each reports a finite validation error and loss; the gradient-trained ones move their
    weights (a swarm keeps its start while no particle beats it: its own test checks it).
    """
    trained = 0
    for kind in ('psik', 'fcn', 'anfis'):
        cfg = ModelConfig(kind=kind, encoder=PRESETS['tiny'][0], decoder=PRESETS['tiny'][1])
        t = trainer(panda, uniform_small, tmp_path / kind, model=cfg, steps=10, eval_every=10,
                    pso_particles=10, pso_batch=256)
        start = [p.detach().clone() for p in t.model.parameters()]
        rec = t.run()
        assert t.step == 10
        moved = any(not torch.equal(a, b) for a, b in zip(start, t.model.parameters()))
        assert moved or kind == 'anfis', kind
        assert 0 < rec['val_dist_mean_m'] < np.inf and np.isfinite(rec['loss'])
        trained += 1
    assert trained == 3


@pytest.mark.parametrize('args,message', [
    (['--model', 'gan'], 'invalid choice'),
    (['--latent-dim', '9'], 'latent dimension'),
    (['--max-time', '-1'], '--max-time'),
    (['--resume'], 'does not exist'),
])
def test_cli_bad_arguments(uniform_small, tmp_path, run_main, args, message):
    """sik-train refuses bad arguments with a short message and a non-zero exit.

    Its ``main`` runs here (test_inputs runs sik-train as a process on a bad dataset).
    """
    from sik_ros.cli.train import main
    code, err = run_main(main, ['--dataset', str(uniform_small.path), '--out',
                                str(tmp_path / 'run'), '--quiet', '--steps', '2', *args])
    assert code not in (0, None)  # as a process's exit status: non-zero
    assert message in err


def test_pso_trains_an_anfis_through_the_same_loop(panda, uniform_small, tmp_path):
    """Particle swarm steps of an ANFIS never raise its best loss, and a resume continues them."""
    anfis = ModelConfig(kind='anfis', anfis_mfs=2)
    whole = trainer(panda, uniform_small, tmp_path / 'whole', model=anfis, steps=20,
                    eval_every=10, checkpoint_every=10, pso_particles=16, pso_batch=256)
    losses = []
    whole.run(progress=lambda step, rec: losses.append(rec['loss']))
    assert len(losses) == 20 and all(b <= a for a, b in zip(losses, losses[1:])), losses
    assert [r['step'] for r in whole.history] == [10, 20]
    part = trainer(panda, uniform_small, tmp_path / 'part', model=anfis, steps=20,
                   eval_every=10, checkpoint_every=10, pso_particles=16, pso_batch=256)
    part.run(max_time=0.0)
    rest = trainer(panda, uniform_small, tmp_path / 'part', model=anfis, steps=20,
                   eval_every=10, checkpoint_every=10, pso_particles=16, pso_batch=256)
    rest.restore(load_checkpoint(tmp_path / 'part' / 'last.pt'))
    rest.run()
    assert rest.step == 20
    assert torch.equal(rest.model.params_flat, whole.model.params_flat)


@pytest.mark.e2e
def test_two_gloo_processes_train_in_sync_and_the_checkpoint_serves(
        panda, uniform_small, tmp_path):
    """Two CPU processes under torchrun: same weights on both ranks; rank 0's model solves."""
    import json
    import os
    from sik_ros.bundles.bundle import build_bundle
    from sik_ros.defaults import TableConfig
    from sik_ros.solver import SelectiveIK
    out = tmp_path / 'ddp'
    env = {**os.environ, 'OMP_NUM_THREADS': '1'}
    run = subprocess.run(
        [os.path.join(os.path.dirname(sys.executable), 'torchrun'), '--standalone',
         '--nproc_per_node', '2', '-m', 'sik_ros.cli.train', '--dataset',
         str(uniform_small.path), '--out', str(out), '--preset', 'tiny', '--steps', '8',
         '--batch-size', '64', '--eval-every', '8', '--checkpoint-every', '8', '--threads', '1',
         '--quiet', '--export', str(out / 'model.pt')],
        capture_output=True, text=True, timeout=300, env=env)
    assert run.returncode == 0, run.stderr[-3000:]
    ranks = [json.loads(line) for line in run.stdout.splitlines() if line.startswith('{')]
    assert sorted(r['rank'] for r in ranks) == [0, 1]
    assert all(r['world_size'] == 2 for r in ranks)
    assert ranks[0]['weights_sha256'] == ranks[1]['weights_sha256']
    assert all(r['step'] == 8 for r in ranks)
    ckpt = load_checkpoint(out / 'last.pt')
    assert ckpt['step'] == 8
    bundle = build_bundle(tmp_path / 'bundle', panda, {'position': out / 'model.pt'},
                          uniform_small, TableConfig(cell=0.1))
    p, _ = panda.fk(panda.lower * 0.3 + panda.upper * 0.7)
    res = SelectiveIK.load(bundle).solve(p, num_solutions=4)
    assert check_served(panda, res, p) >= 1


def test_fresh_samples_and_the_cycle_term_train_and_keep_the_index(
        panda, uniform_small, tmp_path):
    """Fresh batches with the FK and cycle terms lower the FK error and keep the index.

    Batches drawn afresh by torch FK; decoded postures of different indices stay apart (no
    collapse of the posture index).
    """
    t = trainer(panda, uniform_small, tmp_path, steps=300, eval_every=300, sampler='uniform',
                fk_weight=0.05, cycle_weight=1.0)
    before = t.validate()
    after = t.run()
    assert after['val_dist_mean_m'] < 0.7 * before['val_dist_mean_m'], (before, after)
    assert after['cycle'] > 0 and after['fk_other'] > 0  # both terms were in the loss
    assert after['val_index_spread'] > 0.1, after


def test_fresh_batches_are_within_the_limits_and_match_pinocchio(panda, uniform_small, tmp_path):
    """The uniform sampler's joints lie within the limits and its goals are Pinocchio's FK."""
    t = trainer(panda, uniform_small, tmp_path, sampler='uniform')
    q, goal, pos, rot6 = t.fresh_batch(64)
    assert torch.all(q >= torch.as_tensor(panda.lower, dtype=torch.float32))
    assert torch.all(q <= torch.as_tensor(panda.upper, dtype=torch.float32))
    data, fid = panda.model.createData(), find_frame(panda.model, panda.tip_frame)
    for row, g in zip(q.double().numpy()[:8], goal.numpy()):
        pin.framesForwardKinematics(panda.model, data, row)
        assert np.abs(data.oMf[fid].translation - g).max() < 1e-5


def test_init_starts_from_a_model_and_refuses_another_config(panda, uniform_small, tmp_path):
    """--init copies the weights of a matching model; another config is refused."""
    a = trainer(panda, uniform_small, tmp_path / 'a', steps=20)
    a.run()
    export_model(a.checkpoint(), tmp_path / 'a.pt')
    b = trainer(panda, uniform_small, tmp_path / 'b', steps=20)
    b.initialise(load_checkpoint(tmp_path / 'a.pt'), 'a.pt')
    for k, v in a.model.state_dict().items():
        assert torch.equal(v, b.model.state_dict()[k]), k
    assert b.step == 0
    other = ModelConfig(encoder=PRESETS['tiny'][0], decoder=(32, 32), latent_dim=2)
    with pytest.raises(ArtifactMismatch, match='model config'):
        trainer(panda, uniform_small, tmp_path / 'c', model=other).initialise(
            load_checkpoint(tmp_path / 'a.pt'), 'a.pt')


def test_init_widens_the_index_of_a_smaller_model(panda, uniform_small, tmp_path):
    """--init from a model with a smaller index: the wider one starts as the same decoder.

    A 1-d pose model grows a second learned element and the Panda's branch code; whatever the
    new elements' values, the decoder's output is the old model's at the old index, and the
    encoder's old output is kept.
    """
    from sik_ros.learning.models import branch_bits
    small = ModelConfig(goal='pose', latent_dim=1, encoder=PRESETS['tiny'][0],
                        decoder=PRESETS['tiny'][1])
    a = trainer(panda, uniform_small, tmp_path / 'a', model=small, steps=20)
    a.run()
    export_model(a.checkpoint(), tmp_path / 'a.pt')
    wide = ModelConfig(goal='pose', latent_dim=2, encoder=PRESETS['tiny'][0],
                       decoder=PRESETS['tiny'][1],
                       branches=branch_bits(panda.chain, panda.lower, panda.upper))
    b = trainer(panda, uniform_small, tmp_path / 'b', model=wide, steps=20)
    b.initialise(load_checkpoint(tmp_path / 'a.pt'), 'a.pt')
    g, x = torch.randn(6, 9), torch.rand(6, 7) * 2 - 1
    with torch.no_grad():
        z_old, _ = a.model.encode(g, x)
        z_new, _ = b.model.encode(g, x)
        new = torch.cat([z_old, torch.randn(6, 1), torch.sign(torch.randn(6, 2))], 1)
        np.testing.assert_allclose(b.model.decode(g, new).numpy(),
                                   a.model.decode(g, z_old).numpy(), rtol=1e-5, atol=1e-6)
    assert z_new.shape == (6, 4)
    np.testing.assert_allclose(z_new[:, :1].numpy(), z_old.numpy(), rtol=1e-6)
    back = ModelConfig(goal='pose', latent_dim=1, encoder=PRESETS['tiny'][0],
                       decoder=PRESETS['tiny'][1])
    b.run()
    export_model(b.checkpoint(), tmp_path / 'b.pt')
    with pytest.raises(ArtifactMismatch, match='model config'):
        trainer(panda, uniform_small, tmp_path / 'c', model=back).initialise(
            load_checkpoint(tmp_path / 'b.pt'), 'b.pt')


def test_a_pose_model_starts_from_a_position_model_as_that_model(panda, uniform_small, tmp_path):
    """--init of a pose model from a position model: it computes what the position model did.

    Whatever the goal's orientation entries (their inputs start at zero weight), the encoder
    gives the position model's index and the decoder its posture; a pose model cannot start
    a position model.
    """
    a = trainer(panda, uniform_small, tmp_path / 'a', steps=20)
    a.run()
    export_model(a.checkpoint(), tmp_path / 'a.pt')
    pose = ModelConfig(goal='pose', encoder=PRESETS['tiny'][0], decoder=PRESETS['tiny'][1])
    b = trainer(panda, uniform_small, tmp_path / 'b', model=pose, steps=20, cycle_weight=0.1,
                cycle_turn=0.25, rot_weight=4.0)
    b.initialise(load_checkpoint(tmp_path / 'a.pt'), 'a.pt')
    g, x = torch.randn(6, 9), torch.rand(6, 7) * 2 - 1
    with torch.no_grad():
        z_old, _ = a.model.encode(g[:, :3], x)
        z_new, _ = b.model.encode(g, x)
        np.testing.assert_allclose(z_new.numpy(), z_old.numpy(), rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(b.model.decode(g, z_old).numpy(),
                                   a.model.decode(g[:, :3], z_old).numpy(), rtol=1e-5,
                                   atol=1e-6)
    b.run()  # and it trains from there (the pose recipe of sik-build)
    assert b.step == 20 and np.isfinite(b.history[-1]['val_orient_mean_deg'])
    export_model(b.checkpoint(), tmp_path / 'b.pt')
    with pytest.raises(ArtifactMismatch, match='model config'):
        trainer(panda, uniform_small, tmp_path / 'c').initialise(
            load_checkpoint(tmp_path / 'b.pt'), 'b.pt')


def test_a_psik_starts_from_a_sik_model_with_a_standardised_index(panda, uniform_small,
                                                                  tmp_path):
    """--init of a PSIK from a SIK model: the same postures, an index of zero mean, unit spread.

    The encoder's means are SIK's indices standardised over the training rows, the decoder
    gives SIK's posture for each row's own index, the log-variance starts at its small value,
    and the KL weight rises over ``kl_anneal`` steps.
    """
    from sik_ros.learning.train_config import kl_weight_at
    from sik_ros.learning.warm_start import PSIK_LOGVAR_START
    a = trainer(panda, uniform_small, tmp_path / 'a', steps=20)
    a.run()
    export_model(a.checkpoint(), tmp_path / 'a.pt')
    psik = ModelConfig(kind='psik', encoder=PRESETS['tiny'][0], decoder=PRESETS['tiny'][1])
    b = trainer(panda, uniform_small, tmp_path / 'b', model=psik, steps=20, kl_anneal=10)
    b.initialise(load_checkpoint(tmp_path / 'a.pt'), 'a.pt')
    # held-out rows: the standardisation was fitted on training rows, it must hold beyond them
    held_out = b.val_idx
    assert not set(held_out.tolist()) & set(b.train_idx.tolist())
    q, goal, _, _ = b._batch(held_out)
    g, x = b.norm.goal_to_net(goal), b.norm.q_to_net(q)
    with torch.no_grad():
        z_sik, _ = a.model.encode(g, x)
        mu, logvar = b.model.encode(g, x)
        np.testing.assert_allclose(b.model.decode(g, mu).numpy(),
                                   a.model.decode(g, z_sik).numpy(), rtol=1e-4, atol=1e-4)
    assert mu.shape == z_sik.shape == (len(held_out), 4) and len(held_out) == 500
    np.testing.assert_allclose(mu.mean(0).numpy(), 0.0, atol=0.1)
    np.testing.assert_allclose(mu.std(0).numpy(), 1.0, atol=0.1)
    np.testing.assert_allclose(logvar.numpy(), PSIK_LOGVAR_START, atol=1e-6)
    # the documented ramp: from 0 before the first step, by equal steps, to the full weight
    # at step kl_anneal - 1, and the full weight after it
    full, ramp = b.cfg.kl_weight, b.cfg.kl_anneal
    assert ramp == 10
    weights = np.array([kl_weight_at(b.cfg, s) for s in range(2 * ramp)])
    np.testing.assert_allclose(np.diff(np.concatenate([[0.0], weights[:ramp]])), full / ramp,
                               rtol=1e-9)
    np.testing.assert_allclose(weights[ramp - 1:], full, rtol=1e-12)
    b.run()
    assert b.step == 20 and np.isfinite(b.history[-1]['val_dist_mean_m'])
    with pytest.raises(ArtifactMismatch, match='model config'):
        wide = ModelConfig(kind='psik', latent_dim=2, encoder=PRESETS['tiny'][0],
                           decoder=PRESETS['tiny'][1])
        trainer(panda, uniform_small, tmp_path / 'c', model=wide).initialise(
            load_checkpoint(tmp_path / 'a.pt'), 'a.pt')


def test_a_run_stopped_by_time_ends_with_its_validation(panda, uniform_small, tmp_path):
    """A run stopped between validations (max_time) still reports validation figures."""
    t = trainer(panda, uniform_small, tmp_path, steps=60, eval_every=30)
    rec = t.run(max_time=0.0)
    assert rec['step'] == 1 and rec['val_dist_mean_m'] > 0
    assert t.history[-1]['step'] == 1


def test_an_interrupted_run_checkpoints_its_last_step(panda, uniform_small, tmp_path):
    """Ctrl-C (or SIGTERM in sik-train) in the middle of a run saves the steps done so far."""
    t = trainer(panda, uniform_small, tmp_path, steps=60, checkpoint_every=1000)

    def stop_at_7(step, rec):
        if step == 7:
            raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        t.run(progress=stop_at_7)
    assert load_checkpoint(tmp_path / 'last.pt')['step'] == 7
