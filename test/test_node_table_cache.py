"""End to end: sik_node restarted on an arm's cache loads its table of configurations, checked.

Over real DDS, a UR5 from the ``robot_description`` parameter, learning off: the first start
sweeps the table and caches it; a restart loads it (its log says so, the cached file is not
written again) and answers exactly; a restart on a damaged table sets it aside, sweeps it again
and answers exactly.
"""

import pytest

from arm_urdfs import erd_text
import harness
from sik_interfaces.srv import SolveIK
from sik_ros.kinematics.robots import load_robot
from test_node_description import exact_answers, FRAMES, start  # noqa: I100,I201 (test/)

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(300)]


def serve(env, node, cache, log_file, ur5, text):
    """One start with learning off: its log once it answered 5 exact pose goals and stopped."""
    with open(log_file, 'wb') as log:
        proc = start(env, log, cache, description=text, learning=False)
    try:
        client = node.create_client(SolveIK, '/sik_node/solve_ik')
        assert harness.wait_for_service(node, client, proc, 90.0), log_file.read_text()
        assert exact_answers(node, client, ur5, 5, seed=9) == 5
        node.destroy_client(client)
    finally:
        assert harness.stop_node(proc) == 0, log_file.read_text()[-2000:]
    return log_file.read_text()


def test_a_restart_loads_the_cached_table_and_a_damaged_one_is_swept_again(graph, tmp_path):
    """Start: swept, cached; restart: loaded, not rewritten; damaged: set aside, swept again."""
    env, node = graph
    ur5 = load_robot('ur5', None, *FRAMES)
    text, cache = erd_text('ur5'), tmp_path / 'cache'
    first = serve(env, node, cache, tmp_path / 'first.log', ur5, text)
    assert 'table of configurations: loaded' not in first
    files = sorted(cache.rglob('table/seeds.npz'))
    assert len(files) == 1
    stamp = files[0].stat().st_mtime_ns
    again = serve(env, node, cache, tmp_path / 'again.log', ur5, text)
    assert 'table of configurations: loaded from the cache' in again
    assert files[0].stat().st_mtime_ns == stamp
    data = bytearray(files[0].read_bytes())
    data[len(data) // 3] ^= 0x5A
    files[0].write_bytes(bytes(data))
    damaged = serve(env, node, cache, tmp_path / 'damaged.log', ur5, text)
    assert 'set aside' in damaged and 'seeds.npz changed' in damaged
    assert 'table of configurations: loaded' not in damaged
    aside = sorted(cache.rglob('table.damaged-*.reason.txt'))
    assert len(aside) == 1 and 'seeds.npz changed' in aside[0].read_text()
