"""sik-view end to end: the page, and the scene its server sends a browser for a target.

A websocket client speaks viser's wire protocol (zstd-compressed msgpack with binary buffers
after it) as the browser does: it receives the scene, moves the target, and reads back the
arm's meshes, which must sit at the forward kinematics of exact solutions for that target.
"""

import re
import socket
import urllib.request

import msgspec
import numpy as np
import pytest
import viser
from viser.infra._messages import is_binary_placeholder
from websockets.sync.client import connect
import zstandard

from sik_ros.cli.view import main as view_main
from sik_ros.solver import SelectiveIK
from sik_ros.viewer.app import Viewer
from sik_ros.viewer.meshes import ArmMeshes
from sik_ros.viewer.scene import grid_offsets, table

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(180)]

#: A Panda configuration whose tip is the target the client sends [rad].
Q_TARGET = np.array([0.3, -0.4, 0.2, -2.1, 0.1, 1.9, 0.5])


def free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def decode(frame: bytes) -> list:
    """The messages of one server frame, numpy arrays put back in place of their placeholders."""
    size, packed = int.from_bytes(frame[:8], 'little'), int.from_bytes(frame[8:16], 'little')
    inner = msgspec.msgpack.decode(zstandard.ZstdDecompressor().decompress(
        frame[16:16 + packed], max_output_size=size))
    buffers, offset = [], 16 + packed
    for length in inner['binaryBufferLengths']:
        offset += (8 - offset % 8) % 8
        buffers.append(frame[offset:offset + length])
        offset += length

    def fill(value):
        if is_binary_placeholder(value):
            return np.frombuffer(buffers[value['__binary_index']], dtype=value['dtype'])
        if isinstance(value, dict):
            return {k: fill(v) for k, v in value.items()}
        if isinstance(value, list):
            return [fill(v) for v in value]
        return value
    return [fill(m) for m in inner['messages']]


class Browser:
    """What a browser knows of the scene: each arm part's latest instances, the GUI texts."""

    def __init__(self, port: int):
        self.ws = connect(f'ws://127.0.0.1:{port}',
                          subprotocols=[f'viser-v{viser.__version__}'], max_size=None)
        self.parts = {}
        self.markdown = {}

    def receive(self, until, timeout: float = 60.0) -> None:
        """Read frames until ``until()`` holds."""
        import time
        deadline = time.monotonic() + timeout
        while not until():
            assert time.monotonic() < deadline, 'the scene did not arrive'
            try:
                frame = self.ws.recv(timeout=1.0)
            except TimeoutError:
                continue
            for m in decode(frame):
                self._apply(m)

    def _apply(self, m: dict) -> None:
        name = m.get('name', '')
        if m['type'] == 'BatchedMeshesMessage' and name.startswith('/arm/'):
            self.parts[name] = dict(m['props'])
        elif m['type'] == 'SceneNodeUpdateMessage' and name in self.parts:
            self.parts[name].update(m['updates'])
        elif m['type'] == 'GuiMarkdownMessage':
            self.markdown[m['uuid']] = m['props']['_markdown']
        elif m['type'] == 'GuiUpdateMessage' and '_markdown' in m['updates']:
            self.markdown[m['uuid']] = m['updates']['_markdown']

    def move(self, name: str, position, wxyz) -> None:
        """Drag a transform control to a pose, as the page does."""
        msg = viser._messages.TransformControlsUpdateMessage(
            name=name, wxyz=tuple(float(v) for v in wxyz),
            position=tuple(float(v) for v in position))
        self.ws.send(msgspec.msgpack.encode(msg.as_serializable_dict()))

    def instances(self, name: str):
        props = self.parts[name]
        return (np.asarray(props['batched_wxyzs']).reshape(-1, 4),
                np.asarray(props['batched_positions']).reshape(-1, 3))


@pytest.fixture(scope='module')
def panda_viewer():
    ik = SelectiveIK.load('panda')
    viewer = Viewer(ik, port=free_port())
    yield viewer
    viewer.server.stop()


def test_page_is_served(panda_viewer):
    """The server answers the page (viser's client) over HTTP."""
    with urllib.request.urlopen(f'http://127.0.0.1:{panda_viewer.server.get_port()}/',
                                timeout=30) as page:
        assert page.status == 200
        assert 'text/html' in page.headers['Content-Type']
        assert '<title>Viser</title>' in page.read().decode()


def test_scene_for_a_dragged_target(panda_viewer, panda):
    """Dragging the target: the arm's meshes arrive at the FK of exact solutions for it."""
    viewer = panda_viewer
    browser = Browser(viewer.server.get_port())
    n_parts = len(viewer.meshes.parts)
    browser.receive(lambda: len(browser.parts) == n_parts)
    position, quaternion = panda.fk(Q_TARGET)
    x, y, z, w = quaternion
    browser.move('/target', position, (w, x, y, z))
    browser.receive(lambda: viewer.result_position is not None
                    and np.allclose(viewer.result_position, position))
    result = viewer.result
    assert result.success and len(result.solutions) == 16
    qs = np.array([s.q for s in result.solutions])
    for q in qs:                                      # every posture shown reaches the target
        p, quat = panda.fk(q)
        assert np.linalg.norm(p - position) <= 1e-4
        assert abs(abs(float(np.dot(quat, quaternion))) - 1.0) <= 1e-6
    rotations, positions = viewer.meshes.poses_batch(qs)
    offsets = grid_offsets(len(qs), viewer.spacing)
    names = sorted(browser.parts)

    def arrived() -> bool:
        xyz = [browser.instances(name)[1] for name in names]
        return all(x.shape == positions[:, j].shape
                   and np.allclose(x, positions[:, j] + offsets, atol=1e-5)
                   for j, x in enumerate(xyz))
    browser.receive(arrived)
    for j, name in enumerate(names):
        wxyz, _ = browser.instances(name)
        np.testing.assert_allclose(np.abs(np.sum(wxyz * rotations[:, j], axis=1)), 1.0,
                                   atol=1e-5)
    browser.receive(lambda: table(result, 0) in browser.markdown.values())
    assert table(result, 0) in browser.markdown.values()
    shown = [t for t in browser.markdown.values() if t.startswith('solution 1, joints')][0]
    values = [float(v) for v in re.findall(r': ([+-]\d+\.\d+)', shown)]
    np.testing.assert_allclose(values, qs[0], atol=5e-5)
    browser.ws.close()


def test_any_arm(ur5_bundle):
    """A sik-build bundle of another arm (UR5): its parts pose by its own FK."""
    ik = SelectiveIK.load(ur5_bundle[0])
    meshes = ArmMeshes(ik.robot)
    assert meshes.parts
    rng = np.random.default_rng(0)
    nearest = []
    for q in [0.5 * (ik.robot.lower + ik.robot.upper)] + list(
            rng.uniform(ik.robot.lower, ik.robot.upper, (3, ik.robot.dof))):
        _, xyz = meshes.poses(q)
        tip, _ = ik.fk(q)
        nearest.append(np.min(np.linalg.norm(xyz - tip, axis=1)))
    # the last part (the UR5's wrist 3, 8 cm before tool0) moves rigidly with the tip: one
    # distance at every configuration, under 15 cm
    assert len(nearest) == 4 and np.ptp(nearest) < 1e-9 and nearest[0] < 0.15


@pytest.mark.parametrize('args, words', [
    (['--bundle', '/nonexistent/bundle'], '/nonexistent/bundle'),
    (['--robot', 'no_such_robot'], 'no_such_robot'),
])
def test_bad_bundle_is_one_line(tmp_path, capsys, args, words):
    """sik-view on a bad bundle: one line saying why, exit 2."""
    assert view_main(args + ['--port', str(free_port())]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('sik-view: error: ') and words in err[0], err


def test_obstacles_and_path(panda_viewer, panda):
    """A box obstacle enters the ranking (clearance reported); a line path plays on the arm."""
    viewer = panda_viewer
    viewer.add_box()
    assert viewer.result.solutions
    assert all(np.isfinite(s.min_obstacle_distance) for s in viewer.result.solutions)
    viewer.clear_boxes()
    assert all(np.isinf(s.min_obstacle_distance) for s in viewer.result.solutions)
    viewer.path_end.position = tuple(viewer.goal.position + np.array([0.0, 0.08, 0.0]))
    viewer.plan_path()
    assert viewer.path_q is not None and viewer.path_q.shape == (20, 7)
    assert 'success' in viewer.path_text.content
    end, _ = panda.fk(viewer.path_q[-1])
    assert np.linalg.norm(end - np.asarray(viewer.path_end.position)) <= 1e-4
