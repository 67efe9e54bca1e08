"""A pose model's small index: started from a position model's trunks, anchored to a joint."""

import numpy as np
import pytest
import torch

from sik_ros.learning.checkpoints import export_model, load_checkpoint
from sik_ros.learning.models import branch_bits, ModelConfig, PRESETS
from sik_ros.learning.train_config import anchor_weight_at, TrainConfig
from sik_ros.learning.training import Trainer
from sik_ros.learning.warm_start import narrows, widens

pytestmark = pytest.mark.slow

ENC, DEC = PRESETS['tiny']


def trainer(panda, ds, out, model, **kw):
    """A trainer with a tiny, fast config."""
    cfg = TrainConfig(**{'steps': 20, 'batch_size': 256, 'lr': 3e-3, 'warmup': 5,
                         'eval_every': 10, 'checkpoint_every': 20, 'val_rows': 500,
                         'threads': 1, **kw})
    return Trainer(panda, ds, model, cfg, out)


def test_narrows_is_a_smaller_index_of_the_same_layers():
    """A smaller learned index (and a pose goal for a position one) narrows; nothing else."""
    pos = ModelConfig(encoder=ENC, decoder=DEC)
    pose1 = ModelConfig(goal='pose', latent_dim=1, encoder=ENC, decoder=DEC,
                        branches=((1, 1.0, 0.0),))
    assert narrows(pos, pose1) and not widens(pos, pose1)
    assert not narrows(pose1, pos)  # a pose model never starts a position model
    assert not narrows(pos, ModelConfig(latent_dim=2, encoder=ENC, decoder=(32, 32)))
    assert not narrows(pos, pos)


def test_a_pose_model_of_a_fresh_small_index_keeps_the_position_models_trunks(
        panda, uniform_small, tmp_path):
    """--init of a 1-element pose model from a 4-element position model keeps its trunks.

    The encoder's hidden layers compute the position model's (orientation inputs at zero
    weight) and its output layer is fresh; with the new index's columns at zero the decoder
    gives the position model's posture at its mean index over training rows, whatever the
    goal's orientation entries; the branch bits' columns start at zero; and it trains.
    """
    a = trainer(panda, uniform_small, tmp_path / 'a', ModelConfig(encoder=ENC, decoder=DEC))
    a.run()
    export_model(a.checkpoint(), tmp_path / 'a.pt')
    bits = branch_bits(panda.chain, panda.lower, panda.upper)
    pose = ModelConfig(goal='pose', latent_dim=1, encoder=ENC, decoder=DEC, branches=bits)
    b = trainer(panda, uniform_small, tmp_path / 'b', pose)
    fresh = {k: v.clone() for k, v in b.model.state_dict().items()}
    b.initialise(load_checkpoint(tmp_path / 'a.pt'), 'a.pt')
    state = b.model.state_dict()
    last = 'encoder.%d.' % (len(ENC) * 2)
    assert torch.equal(state[last + 'weight'], fresh[last + 'weight'])
    g, x = torch.randn(6, 9), torch.rand(6, 7) * 2 - 1
    q, goal, _, _ = b._batch(b.train_idx[:20_000])
    with torch.no_grad():
        z_old, _ = a.model.encode(a.norm.goal_to_net(goal)[:, :3], a.norm.q_to_net(q))
        mean = z_old.mean(0, keepdim=True)
        np.testing.assert_allclose(b.model.encoder[:-1](torch.cat([g, x], 1)).numpy(),
                                   a.model.encoder[:-1](torch.cat([g[:, :3], x], 1)).numpy(),
                                   rtol=1e-5, atol=1e-6)
        w = b.model.decoder[0].weight
        np.testing.assert_array_equal(w[:, 3:9].numpy(), 0.0)  # orientation inputs
        np.testing.assert_array_equal(w[:, 10:].numpy(), 0.0)  # the branch bits
        w[:, 9] = 0.0
        z = torch.cat([torch.randn(6, 1), torch.sign(torch.randn(6, len(bits)))], 1)
        np.testing.assert_allclose(b.model.decode(g, z).numpy(),
                                   a.model.decode(g[:, :3], mean.expand(6, -1)).numpy(),
                                   rtol=1e-4, atol=1e-5)
    b.initialise(load_checkpoint(tmp_path / 'a.pt'), 'a.pt')
    b.run()
    assert b.step == 20 and np.isfinite(b.history[-1]['val_orient_mean_deg'])


def test_the_anchor_pulls_the_index_to_a_joint_and_is_released(panda, uniform_small, tmp_path):
    """The anchor draws the first index element to the joint, then falls linearly to zero.

    Its weight is the full one at the first step, falls by equal steps, and is zero (the
    term out of the loss) from ``anchor_steps`` on.
    """
    pose = ModelConfig(goal='pose', latent_dim=1, encoder=ENC, decoder=DEC)
    t = trainer(panda, uniform_small, tmp_path, pose, steps=150, eval_every=150,
                fk_weight=0.0, anchor_joint=6, anchor_weight=10.0, anchor_steps=100)
    weights = np.array([anchor_weight_at(t.cfg, s) for s in range(120)])
    assert weights[0] == 10.0 and np.all(weights[100:] == 0.0)
    np.testing.assert_allclose(np.diff(weights[:101]), -0.1, rtol=1e-9)
    q, goal, _, _ = t._batch(t.val_idx)
    g, x = t.norm.goal_to_net(goal), t.norm.q_to_net(q)

    def gap():
        with torch.no_grad():
            return float(torch.mean((t.model.encode(g, x)[0][:, 0] - x[:, 6]) ** 2))
    before = gap()
    t.cfg = TrainConfig(**{**t.cfg.__dict__, 'steps': 50})
    assert 'anchor' in t.run()
    assert gap() < 0.2 * before, (before, gap())
    t.cfg = TrainConfig(**{**t.cfg.__dict__, 'steps': 150})
    assert 'anchor' not in t.run()
    assert anchor_weight_at(TrainConfig(anchor_weight=1.0), 0) == 0.0  # no joint: no anchor


@pytest.mark.parametrize('args,message', [
    (['--model', 'fcn', '--anchor-joint', '6'], '--anchor-joint'),
    (['--anchor-joint', '7'], 'anchor joint 7'),
    (['--anchor-joint', '6', '--anchor-steps', '-1'], 'anchor_steps'),
])
def test_cli_refuses_a_bad_anchor(uniform_small, tmp_path, run_main, args, message):
    """sik-train refuses an anchor on a model without an index or beyond the joints."""
    from sik_ros.cli.train import main
    code, err = run_main(main, ['--dataset', str(uniform_small.path), '--out',
                                str(tmp_path / 'run'), '--quiet', '--steps', '2', *args])
    assert code not in (0, None)
    assert message in err
