"""A bundle's NumPy twins: the same networks as its torch models, loaded without torch."""

import json
import subprocess
import sys

import numpy as np
import pytest
import torch

from sik_ros.bundles.bundle import load_bundle, read_bundle_manifest
from sik_ros.errors import CorruptArtifact
from sik_ros.learning.checkpoints import load_checkpoint, model_from_checkpoint
from sik_ros.learning.twins import load_twin, NumpySIK
from sik_ros.solver.codec import NumpyMLP


def test_twins_compute_what_the_torch_models_compute(tiny_bundle):
    """Each goal's twin encodes and decodes as its checkpoint's torch model (float32)."""
    manifest = read_bundle_manifest(tiny_bundle)
    checked = 0
    for goal, files in manifest['models'].items():
        assert 'twin' in files, goal
        twin, cfg, norm, own = load_twin(tiny_bundle / files['twin'])
        model, cfg_t, norm_t = model_from_checkpoint(load_checkpoint(tiny_bundle / files['model']))
        assert isinstance(twin, NumpySIK) and cfg == cfg_t and norm == norm_t
        rng = np.random.default_rng(1)
        goal_in = rng.standard_normal((5, cfg.goal_dim)).astype(np.float32)
        z = rng.standard_normal((5, cfg.latent_dim)).astype(np.float32)
        x = rng.uniform(-1, 1, (5, cfg.dof)).astype(np.float32)
        with torch.no_grad():
            dec_t = model.decoder(torch.from_numpy(np.c_[goal_in, z])).numpy()
            enc_t = model.encoder(torch.from_numpy(np.c_[goal_in, x])).numpy()
        assert np.allclose(NumpyMLP(twin.decoder)(np.c_[goal_in, z]), dec_t, atol=1e-5)
        assert np.allclose(NumpyMLP(twin.encoder)(np.c_[goal_in, x]), enc_t, atol=1e-5)
        checked += 1
    assert checked == 2


@pytest.mark.e2e
def test_a_bundle_with_twins_serves_without_torch(tiny_bundle, panda):
    """Loading and solving from the twins imports no torch (a node starts sooner)."""
    p, quat = (v.tolist() for v in panda.fk((panda.lower + panda.upper) / 2))
    code = (
        'import sys, json\n'
        'from sik_ros import SelectiveIK\n'
        f'ik = SelectiveIK.load({str(tiny_bundle)!r})\n'
        f'res = ik.solve({p!r}, {quat!r}, num_solutions=4)\n'
        'raw = ik.solve(' + repr(p) + ', refine=False, num_solutions=2)\n'
        'print(json.dumps([bool(res.success), len(raw.solutions), "torch" in sys.modules]))\n')
    run = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    success, raw, torch_loaded = json.loads(run.stdout.strip().splitlines()[-1])
    assert success and raw == 2 and not torch_loaded


def test_a_damaged_twin_is_refused(tiny_bundle, tmp_path):
    """A truncated twin is a CorruptArtifact, naming the file; the bundle is not loaded."""
    import shutil
    copy = tmp_path / 'bundle'
    shutil.copytree(tiny_bundle, copy)
    twin = copy / read_bundle_manifest(copy)['models']['pose']['twin']
    twin.write_bytes(twin.read_bytes()[:200])
    with pytest.raises(CorruptArtifact, match='twin'):
        load_bundle(copy)
