"""colcon: both packages build in a fresh workspace, and the installed node answers over ROS 2.

The workspace holds a copy of the package files (``src/sik_ros``, with ``sik_interfaces/`` inside
it, as a ``git clone`` lays them out); colcon runs from the venv with the environment that
``scripts/env.sh`` sets. One build of both packages serves the layout checks and the node; it
starts in the background as the session starts (:func:`start_background`, called by conftest,
which runs this module's tests last), at the lowest CPU priority (the idle scheduling class):
it runs on the CPU time the other tests leave (a second core, their waits).
"""

import json
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
from typing import Dict, Optional

import numpy as np
import pytest

from sik_interfaces.srv import SolveIK
from sik_ros.ros import launch

pytestmark = [pytest.mark.e2e, pytest.mark.slow, pytest.mark.timeout(600)]

REPO = Path(__file__).resolve().parents[1]
#: What the two packages are made of (everything else in the repository is not installed).
PACKAGE_FILES = ('package.xml', 'setup.py', 'setup.cfg', 'resource', 'config', 'sik_ros',
                 'sik_interfaces')
#: The Panda's ready posture [rad]: its tip is the node's target.
READY = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)
PYTHON_DIR = f'python{sys.version_info[0]}.{sys.version_info[1]}'
NEEDED = """Build both packages:
    colcon build --paths src/sik_ros src/sik_ros/sik_interfaces"""
#: The build of :func:`built`: both packages, as NEEDED says, without their tests.
BUILD = ['build', '--paths', 'src/sik_ros', 'src/sik_ros/sik_interfaces', '--cmake-args',
         '-DBUILD_TESTING=OFF']
#: Runs a command (in a session of its own) in the idle scheduling class, its children too: CPU
#: time only when no other process wants it (nice 19 where the class cannot be had). Where
#: Linux groups each session for scheduling (autogroup), the session's group gets nice 19.
IDLE = ('import os, sys\n'
        'try:\n'
        '    with open("/proc/self/autogroup", "w") as f:\n'
        '        f.write("19")\n'
        'except OSError:\n'
        '    pass\n'
        'try:\n'
        '    os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))\n'
        'except (AttributeError, OSError):\n'
        '    os.nice(19)\n'
        'os.execv(sys.argv[1], sys.argv[1:])\n')
#: The build started by :func:`start_background`, until :func:`built` takes it.
_background: Dict[str, dict] = {}


def make_workspace(root: Path) -> Path:
    """A colcon workspace ``root`` with this repository's packages in ``src/sik_ros``."""
    src = root / 'src' / 'sik_ros'
    src.mkdir(parents=True)
    ignore = shutil.ignore_patterns('__pycache__', '*.pyc', '*.egg-info', 'build', 'install',
                                    'log')
    for name in PACKAGE_FILES:
        path = REPO / name
        if path.is_dir():
            shutil.copytree(path, src / name, ignore=ignore)
        else:
            shutil.copy2(path, src / name)
    return root


def colcon_env(ament_prefix_path: Optional[Path]) -> dict:
    """The environment of ``source scripts/env.sh`` (the venv first on PATH, AMENT_PREFIX_PATH)."""
    dropped = ('PYTHONPATH', 'AMENT_PREFIX_PATH', 'CMAKE_PREFIX_PATH', 'COLCON')
    env = {k: v for k, v in os.environ.items() if k not in dropped}
    env['PATH'] = str(Path(sys.executable).parent) + os.pathsep + env.get('PATH', '')
    env['VIRTUAL_ENV'] = sys.prefix
    env['RMW_IMPLEMENTATION'] = 'rmw_fastrtps_cpp'
    if ament_prefix_path is not None:
        env['AMENT_PREFIX_PATH'] = str(ament_prefix_path)
    return env


def colcon(ws: Path, args, env) -> subprocess.CompletedProcess:
    """Run ``colcon <args>`` in ``ws``; output (both streams) in ``.stdout``."""
    return subprocess.run([str(Path(sys.executable).parent / 'colcon'), *args], cwd=ws, env=env,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          timeout=540)


def start_build(root: Path, idle: bool) -> dict:
    """Start :data:`BUILD` in a new workspace ``root`` (in the idle class if ``idle``).

    Returns the workspace, its environment, the colcon process (a session of its own) and the
    file of its output (both streams).
    """
    ws = make_workspace(root)
    env = colcon_env(sys.prefix)
    output = root / 'colcon_output.txt'
    command = [str(Path(sys.executable).parent / 'colcon'), *BUILD]
    if idle:
        command = [sys.executable, '-c', IDLE, *command]
    with open(output, 'wb') as out:
        proc = subprocess.Popen(command, cwd=ws, env=env, stdout=out, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, start_new_session=True)
    return {'ws': ws, 'env': env, 'proc': proc, 'output': output}


def stop_build(build: dict) -> None:
    """Stop a build's colcon and every process it started, if still running."""
    proc = build['proc']
    if proc.poll() is None:
        for sig, wait in ((signal.SIGTERM, 10.0), (signal.SIGKILL, 10.0)):
            try:
                os.killpg(proc.pid, sig)
            except ProcessLookupError:
                break
            try:
                proc.wait(wait)
                break
            except subprocess.TimeoutExpired:
                pass


def start_background(config, items) -> None:
    """Start the build of :func:`built` in the idle class if one of ``items`` needs it.

    conftest calls this once the tests are collected (and :func:`stop_background` as the
    session ends); the build is the same, only started earlier.
    """
    if 'build' not in _background and any('built' in item.fixturenames for item in items):
        _background['build'] = start_build(config._tmp_path_factory.mktemp('colcon_ws'), True)


def stop_background() -> None:
    """Stop the build of :func:`start_background` if no test took it (the session stopped)."""
    build = _background.pop('build', None)
    if build is not None:
        stop_build(build)


def sourced(ws: Path, command: str, env) -> subprocess.CompletedProcess:
    """Run a bash ``command`` after ``source install/setup.bash``."""
    return subprocess.run(['bash', '-c', f'source install/setup.bash && {command}'], cwd=ws,
                          env=env, capture_output=True, text=True, timeout=120)


@pytest.fixture(scope='module')
def built(tmp_path_factory):
    """A workspace in which ``colcon build`` built sik_interfaces and sik_ros.

    The build started in the background (:func:`start_background`) is waited for; without
    one, it is started here.
    """
    build = _background.pop('build', None) or start_build(
        tmp_path_factory.mktemp('colcon_ws'), False)
    try:
        build['proc'].wait(540)
    finally:
        stop_build(build)
    output = build['output'].read_text(errors='replace')
    assert build['proc'].returncode == 0, output[-4000:]
    return build['ws'], build['env']


def test_layout(built):
    """The install space has what ``ros2 run`` and ament look for, the Panda model, the kernels."""
    ws, _ = built
    share = ws / 'install' / 'sik_ros' / 'share'
    node = ws / 'install' / 'sik_ros' / 'lib' / 'sik_ros' / 'sik_node'
    assert node.is_file() and os.access(node, os.X_OK)
    assert (share / 'sik_ros' / 'package.xml').read_bytes() == (REPO / 'package.xml').read_bytes()
    configs = sorted(p.name for p in (REPO / 'config').glob('*.yaml'))
    assert configs and sorted(p.name for p in (share / 'sik_ros' / 'config').iterdir()) == configs
    assert (share / 'ament_index' / 'resource_index' / 'packages' / 'sik_ros').is_file()
    bundle = REPO / 'sik_ros' / 'bundles' / 'panda'
    installed = (ws / 'install' / 'sik_ros' / 'lib' / PYTHON_DIR / 'site-packages' / 'sik_ros'
                 / 'bundles' / 'panda')
    files = [p for p in bundle.rglob('*') if p.is_file()]
    assert any(p.parent != bundle for p in files)  # the shipped baselines' folder too
    for path in files:
        rel = path.relative_to(bundle)
        assert (installed / rel).read_bytes() == path.read_bytes(), rel
    # the build compiled the installed copy's kernels into their cache
    assert list((installed.parent.parent / 'kernels' / '__pycache__').glob('*.nbi'))
    for tool in ('sik-build', 'sik-solve', 'sik-view'):
        assert (ws / 'install' / 'sik_ros' / 'lib' / 'sik_ros' / tool).is_file(), tool
    iface = ws / 'install' / 'sik_interfaces' / 'share'
    assert (iface / 'ament_index' / 'resource_index' / 'packages' / 'sik_interfaces').is_file()


def test_imports_from_install_space(built):
    """After ``source install/setup.bash``, sik_ros and sik_interfaces come from the install."""
    ws, env = built
    code = ('import sik_interfaces, sik_ros; from sik_interfaces.srv import SolveIK, SolvePath; '
            'from ament_index_python.packages import get_package_share_directory as share; '
            'print(sik_interfaces.__file__); print(sik_ros.__file__); print(share("sik_ros"))')
    run = sourced(ws, f'cd / && python -c {code!r}', env)
    assert run.returncode == 0, run.stderr
    iface, lib, share = run.stdout.split()
    assert iface.startswith(str(ws / 'install' / 'sik_interfaces')), iface
    assert lib.startswith(str(ws / 'install' / 'sik_ros')), lib
    assert share == str(ws / 'install' / 'sik_ros' / 'share' / 'sik_ros')


#: A client run from the install space too (its messages must be the node's own).
CLIENT = """
import json, sys
import rclpy
from sik_ros.ros.client import SolveIKClient
from sik_ros.ros.client import pose_request
rclpy.init()
with SolveIKClient() as client:
    if not client.wait_for_service(120.0):
        sys.exit('no service')
    answer = client.call(pose_request(json.loads(sys.argv[1]), max_solutions=4), timeout=30.0)
rclpy.shutdown()
if answer is None:
    sys.exit('no answer')
print(json.dumps({'code': answer.error_code, 'message': answer.message,
                  'q': [list(s.joint_state.position) for s in answer.solutions]}))
"""


def test_installed_node_answers(built, panda, tmp_path):
    """The installed sik_node (as ``ros2 run sik_ros sik_node`` starts it) answers SolveIK."""
    ws, env = built
    graph = launch.ros_env()
    env = dict(env, **{k: graph[k] for k in ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE')})
    params = ws / 'install' / 'sik_ros' / 'share' / 'sik_ros' / 'config' / 'panda.yaml'
    log_path = tmp_path / 'node.log'
    with open(log_path, 'wb') as log:
        proc = subprocess.Popen(
            ['bash', '-c', 'source install/setup.bash && exec install/sik_ros/lib/sik_ros/sik_node'
             f' --ros-args --params-file {params}'], cwd=ws, env=env, stdout=log,
            stderr=subprocess.STDOUT)
    try:
        position, _ = panda.fk(np.array(READY))
        (tmp_path / 'client.py').write_text(CLIENT)
        run = sourced(ws, f"cd / && python {tmp_path / 'client.py'} "
                          f"'{json.dumps(position.tolist())}'", env)
        assert run.returncode == 0, run.stderr + log_path.read_text()
        answer = json.loads(run.stdout)
        assert answer['code'] == SolveIK.Response.SUCCESS, answer['message']
        reached, _ = panda.fk(np.array(answer['q'][0]))
        assert np.linalg.norm(reached - position) <= 1e-4
    finally:
        assert launch.stop_node(proc) == 0, log_path.read_text()


@pytest.mark.parametrize('case', ['unsourced', 'stale'])
def test_plain_build_stops_with_what_to_run(case, tmp_path):
    """A plain ``colcon build`` that cannot see a matching sik_interfaces says what to run."""
    ws = make_workspace(tmp_path / 'ws')
    prefix = None
    if case == 'stale':    # an underlay whose sik_interfaces was built from other definitions
        prefix = tmp_path / 'underlay'
        index = prefix / 'share' / 'ament_index' / 'resource_index' / 'packages'
        index.mkdir(parents=True)
        (index / 'sik_interfaces').touch()
        (prefix / 'share' / 'sik_interfaces' / 'srv').mkdir(parents=True)
        (prefix / 'share' / 'sik_interfaces' / 'srv' / 'SolveIK.srv').write_text('int32 old\n')
    run = colcon(ws, ['build'], colcon_env(prefix))
    assert run.returncode != 0
    assert NEEDED in run.stdout, run.stdout[-3000:]
    if case == 'stale':
        assert 'differs from this source' in run.stdout
    assert not (ws / 'install' / 'sik_ros' / 'lib' / 'sik_ros' / 'sik_node').exists()
