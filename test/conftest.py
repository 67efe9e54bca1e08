"""Shared fixtures: the Panda robot and small datasets, built once per session."""

import os
import subprocess
import sys

import pytest

from sik_ros.kinematics.robots import load_robot
from sik_ros.tables.dataset import collect

os.environ.setdefault('OMP_NUM_THREADS', '1')

#: Fixtures that start a process (``ur5_bundle`` runs sik-build; ``graph`` is for tests that
#: start a sik_node): every test that uses one is ``e2e``. Other tests carry their markers
#: themselves (``pytestmark`` or a decorator).
E2E_FIXTURES = {'graph', 'ur5_bundle'}
#: Test modules that start slow work in the background once the tests are collected (they
#: define ``start_background(config, items)`` and ``stop_background()``; test_colcon's build):
#: their tests run last, so that the work has the whole session to be done in.
_background_modules = []


def _background_module(item):
    """The module of ``item`` if it starts work in the background, else None."""
    module = getattr(item, 'module', None)
    return module if hasattr(module, 'start_background') else None


def pytest_collection_modifyitems(config, items):
    """Mark the tests that use a fixture starting a process as ``e2e``; background ones last."""
    for item in items:
        if E2E_FIXTURES & set(getattr(item, 'fixturenames', ())):
            item.add_marker(pytest.mark.e2e)
    items.sort(key=lambda item: _background_module(item) is not None)


def pytest_collection_finish(session):
    """Start the background work of the modules that have tests to run."""
    if session.config.option.collectonly:
        return
    for item in session.items:
        module = _background_module(item)
        if module is not None and module not in _background_modules:
            _background_modules.append(module)
            module.start_background(session.config,
                                    [i for i in session.items if _background_module(i) is module])


def pytest_sessionfinish(session):
    """Stop background work that no test took (the session ended early)."""
    while _background_modules:
        _background_modules.pop().stop_background()


@pytest.fixture(scope='session')
def panda():
    """The Panda arm (7 joints, panda_link0 -> panda_hand_tcp)."""
    return load_robot('panda')


@pytest.fixture(scope='session')
def grid90(panda, tmp_path_factory):
    """The Algorithm 1 grid of the Panda at 90 degrees (4,608 rows)."""
    return collect(panda, tmp_path_factory.mktemp('ds') / 'grid90', interval_deg=90.0)


@pytest.fixture(scope='session')
def uniform_small(panda, tmp_path_factory):
    """6,000 configurations drawn uniformly within the Panda's limits."""
    return collect(panda, tmp_path_factory.mktemp('ds') / 'uniform', sampler='uniform',
                   samples=6000, seed=3)


def build_tiny_bundle(robot, dataset, out, steps=400):
    """Train tiny SIK position and pose models on ``dataset`` and bundle them with their tables."""
    from sik_ros.bundles.bundle import build_bundle
    from sik_ros.defaults import TableConfig
    from sik_ros.learning.checkpoints import export_model
    from sik_ros.learning.models import ModelConfig, PRESETS
    from sik_ros.learning.train_config import TrainConfig
    from sik_ros.learning.training import Trainer
    models = {}
    for goal, latent in (('position', 4), ('pose', 1)):
        cfg = ModelConfig(goal=goal, latent_dim=latent, encoder=PRESETS['small'][0],
                          decoder=PRESETS['small'][1])
        trainer = Trainer(robot, dataset, cfg,
                          TrainConfig(steps=steps, batch_size=512, lr=3e-3, warmup=10,
                                      eval_every=steps, checkpoint_every=steps, val_rows=500,
                                      threads=1), out / f'run_{goal}')
        trainer.run()
        models[goal] = export_model(trainer.checkpoint(), out / f'{goal}.pt')
    # the position table keeps decoded postures, as bundled
    return build_bundle(out / 'bundle', robot, models, dataset, TableConfig(cell=0.08))


@pytest.fixture(scope='session')
def tiny_bundle(panda, uniform_small, tmp_path_factory):
    """A bundle of tiny SIK position and pose models trained for seconds (a real pipeline)."""
    return build_tiny_bundle(panda, uniform_small, tmp_path_factory.mktemp('bundle'))


@pytest.fixture(scope='session')
def ur5():
    """UR5: 6 joints, every one with limits of +-2 pi (or a whole turn)."""
    return load_robot('ur5')


@pytest.fixture(scope='session')
def ur5_bundle(tmp_path_factory):
    """A tiny UR5 bundle made by ``sik-build`` end to end (tiny model, small sampler)."""
    out = tmp_path_factory.mktemp('arms') / 'ur5'
    # --time 22: about 9 s of training after the other stages' estimate (13 s; they take under
    # 1 s before the training here), room for a machine half as fast again (a build refuses to
    # start with under 5 s left to train); every test of this bundle passed with --time 20,
    # and 30 cost 8 s more for the same checks
    cmd = [sys.executable, '-m', 'sik_ros.cli.build', '--robot', 'ur5', '--out', str(out),
           '--time', '22', '--rows', '20000', '--preset', 'tiny', '--check-targets', '20',
           '--quiet']
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    return out, run.stdout


@pytest.fixture(scope='module')
def graph(request):
    """An isolated ROS graph on a random domain, and an rclpy node in this process."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions
    import harness
    env = harness.ros_env()
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(request.module.__name__.split('.')[-1])
    yield env, node
    node.destroy_node()
    rclpy.shutdown()


@pytest.fixture
def run_main(capsys):
    """Call a command's ``main(argv)`` in this process; returns its exit code and its stderr.

    An exception other than SystemExit (a traceback, as a process would print it) fails the
    test. Each command keeps a test that runs it as a process (its exit code and stderr as a
    shell sees them).
    """
    def run(main, argv):
        capsys.readouterr()
        try:
            code = main(list(argv))
        except SystemExit as exc:
            code = exc.code
        return code, capsys.readouterr().err
    return run
