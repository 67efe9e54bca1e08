"""Models: shapes, normalisation, differentiable FK, PSIK's KL, ANFIS."""

import numpy as np
import pytest
import torch

from sik_ros.errors import InvalidArgument
from sik_ros.learning.models import (anfis_forward, anfis_sizes, build_model, kl_normal,
                                     ModelConfig, Normalizer, PRESETS, TorchChain)


def tiny(kind='sik', goal='position', latent=None):
    """A tiny model config."""
    enc, dec = PRESETS['tiny']
    latent = latent or (4 if goal == 'position' else 1)
    return ModelConfig(kind=kind, goal=goal, latent_dim=latent, encoder=enc, decoder=dec)


@pytest.mark.parametrize('kind,goal', [('sik', 'position'), ('sik', 'pose'),
                                       ('psik', 'position'), ('fcn', 'position'),
                                       ('anfis', 'position')])
def test_output_shapes(kind, goal):
    """Every model maps a batch of goals (and joints) to a batch of 7 joint values."""
    cfg = tiny(kind, goal)
    model = build_model(cfg).eval()
    g = torch.randn(5, cfg.goal_dim)
    if kind in ('sik', 'psik'):
        x_hat, mu, logvar = model(g, torch.randn(5, 7))
        assert mu.shape == (5, cfg.latent_dim)
        assert (logvar is None) == (kind == 'sik')
    else:
        x_hat = model(g)
    assert x_hat.shape == (5, 7)


def test_paper_preset_has_the_papers_sizes():
    """The paper preset: encoder 2048-2048-1024-512-d, decoder 512-1024-1024-512-n."""
    model = build_model(ModelConfig(encoder=PRESETS['paper'][0], decoder=PRESETS['paper'][1]))
    enc = [m.out_features for m in model.encoder if isinstance(m, torch.nn.Linear)]
    dec = [m.out_features for m in model.decoder if isinstance(m, torch.nn.Linear)]
    assert enc == [2048, 2048, 1024, 512, 4] and dec == [512, 1024, 1024, 512, 7]
    assert sum(isinstance(m, torch.nn.ELU) for m in model.decoder) == 4


def test_normalisation_round_trip(panda):
    """Joints map to [-1, 1] at the limits and back; goals are centred and scaled."""
    norm = Normalizer(tuple(panda.lower), tuple(panda.upper), (0.1, 0.0, 0.3), 0.5)
    q = torch.tensor(np.stack([panda.lower, panda.upper]), dtype=torch.float64)
    x = norm.q_to_net(q)
    torch.testing.assert_close(x, torch.tensor([[-1.0] * 7, [1.0] * 7], dtype=torch.float64))
    torch.testing.assert_close(norm.q_from_net(x), q)
    g = norm.goal_to_net(torch.tensor([[0.6, 0.0, 0.3]], dtype=torch.float64))
    torch.testing.assert_close(g, torch.tensor([[1.0, 0.0, 0.0]], dtype=torch.float64))


def test_torch_fk_matches_pinocchio(panda):
    """The differentiable torch FK equals Pinocchio's frame placement (float64, 1e-9 m)."""
    chain = TorchChain(panda.chain, dtype=torch.float64)
    q = np.random.default_rng(0).uniform(panda.lower, panda.upper, size=(40, 7))
    p, r = chain(torch.from_numpy(q))
    for i in range(len(q)):
        ref = panda.pin_placement(q[i])
        np.testing.assert_allclose(p[i].numpy(), ref.translation, atol=1e-9)
        np.testing.assert_allclose(r[i].numpy(), ref.rotation, atol=1e-9)
    qt = torch.from_numpy(q).requires_grad_()
    chain(qt)[0].sum().backward()
    assert torch.all(torch.isfinite(qt.grad))


def test_kl_is_the_closed_form():
    """The KL term of PSIK equals the closed form of KL(N(mu, s^2) || N(0, 1)) summed over dims."""
    mu = torch.tensor([[0.5, -1.0]])
    logvar = torch.tensor([[0.2, -0.3]])
    var = logvar.exp()
    expected = 0.5 * torch.sum(var + mu ** 2 - 1 - logvar)
    torch.testing.assert_close(kl_normal(mu, logvar)[0], expected)
    assert float(kl_normal(torch.zeros(1, 3), torch.zeros(1, 3))[0]) == 0.0
    dist_kl = torch.distributions.kl_divergence(
        torch.distributions.Normal(mu, var.sqrt()), torch.distributions.Normal(0.0, 1.0)).sum()
    torch.testing.assert_close(kl_normal(mu, logvar)[0], dist_kl)


def test_anfis_batch_of_parameter_vectors():
    """ANFIS evaluates many parameter vectors at once, with 2^3 rules for 3 inputs."""
    cfg = tiny('anfis')
    d, rules, total = anfis_sizes(cfg)
    assert (d, rules) == (3, 8)
    params = torch.randn(4, total)
    out = anfis_forward(cfg, params, torch.randn(6, 3))
    assert out.shape == (4, 6, 7)
    one = anfis_forward(cfg, params[1:2], torch.randn(6, 3))
    assert one.shape == (1, 6, 7)


@pytest.mark.parametrize('kw', [{'kind': 'gan'}, {'goal': 'joint'}, {'latent_dim': 0},
                                {'latent_dim': 8}])
def test_bad_config_is_refused(kw):
    """Unknown kinds or goals and latent sizes outside 1..7 are refused."""
    with pytest.raises(InvalidArgument):
        ModelConfig(**kw)


@pytest.mark.parametrize('kind', ['sik', 'psik'])
def test_the_solver_runs_the_networks_in_numpy_as_torch_does(kind):
    """The solver's NumPy twins of the encoder and decoder give torch's outputs (float32).

    A model with another kind of layer is run by torch itself (no twin).
    """
    from sik_ros.solver.codec import NumpyMLP
    torch.manual_seed(0)
    cfg = tiny(kind, 'pose')
    model = build_model(cfg).eval()
    g, x = torch.randn(9, cfg.goal_dim), torch.randn(9, cfg.dof)
    with torch.no_grad():
        mu, _ = model.encode(g, x)
        out = model.decode(g, mu)
    enc, dec = NumpyMLP.of(model.encoder), NumpyMLP.of(model.decoder)
    h = enc(torch.cat([g, x], 1).numpy())[:, :cfg.latent_dim]
    np.testing.assert_allclose(h, mu.numpy(), rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(dec(np.concatenate([g.numpy(), h], 1)), out.numpy(),
                               rtol=1e-5, atol=1e-5)
    odd = torch.nn.Sequential(torch.nn.Linear(3, 4), torch.nn.ReLU(), torch.nn.Linear(4, 2))
    assert NumpyMLP.of(odd) is None


def test_branch_bits_are_the_arms_flip_joints(panda, ur5):
    """The Panda's shoulder (joint 2) and wrist (joint 6) flips; the UR5's wrist (joint 5).

    The Panda's elbow lines its neighbours up only outside its limits (q4 < 0); a bit is the
    sign of sin(q - s) with s the lining-up angle (0 or pi), in normalised joint units.
    """
    from sik_ros.learning.models import branch_bits
    bits = branch_bits(panda.chain, panda.lower, panda.upper)
    assert [b[0] for b in bits] == [1, 5]
    assert [b[0] for b in branch_bits(ur5.chain, ur5.lower, ur5.upper)] == [4]
    q = np.random.default_rng(0).uniform(panda.lower, panda.upper, (200, 7))
    x = (q - (panda.lower + panda.upper) / 2) / ((panda.upper - panda.lower) / 2)
    for j, scale, offset in bits:
        s = np.sin(x[:, j] * scale + offset)
        # the sign flips where the joint crosses its lining-up angle: q2 = 0, q6 = pi
        cross = 0.0 if j == 1 else np.pi
        assert np.all(np.sign(s) == np.sign(s[0]) * np.sign(q[:, j] - cross)
                      * np.sign(q[0, j] - cross))


def test_the_branch_code_follows_the_learned_index(panda):
    """With a branch code the index is the encoder's output and the bits (torch and NumPy)."""
    from dataclasses import asdict
    from sik_ros.learning.models import branch_bits
    from sik_ros.solver.codec import branch_code, branch_codes, NumpyMLP
    bits = branch_bits(panda.chain, panda.lower, panda.upper)
    enc, dec = PRESETS['tiny']
    cfg = ModelConfig(goal='pose', latent_dim=1, encoder=enc, decoder=dec, branches=bits)
    assert cfg.index_dim == 3 and ModelConfig.from_dict(asdict(cfg)) == cfg
    model = build_model(cfg).eval()
    torch.manual_seed(1)
    g, x = torch.randn(9, 9), torch.rand(9, 7) * 2 - 1
    with torch.no_grad():
        z, _ = model.encode(g, x)
        out = model.decode(g, z)
    assert z.shape == (9, 3) and set(z[:, 1:].unique().tolist()) <= {-1.0, 1.0}
    h = NumpyMLP.of(model.encoder)(torch.cat([g, x], 1).numpy())
    np.testing.assert_allclose(h[:, 0], z[:, 0].numpy(), rtol=1e-5, atol=1e-5)
    np.testing.assert_array_equal(branch_code(bits, x.numpy()), z[:, 1:].numpy())
    assert out.shape == (9, 7)
    codes = sorted(map(tuple, branch_codes(bits).tolist()))
    assert codes == [(-1, -1), (-1, 1), (1, -1), (1, 1)]
    with pytest.raises(InvalidArgument):
        ModelConfig(kind='psik', branches=bits)
