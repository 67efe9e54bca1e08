"""Starting and stopping sik_node as a process on an isolated ROS graph.

Used by the demo (``make run``), the end-to-end tests and the service benchmarks: a node on a
domain of its own (:func:`ros_env`), started with ``config/panda.yaml`` and ``-p`` overrides
(:func:`launch_node`), waited for (:func:`wait_for_service`) and stopped with SIGINT
(:func:`stop_node`).
"""

import json
import os
from pathlib import Path
import random
import signal
import subprocess
import sys
import time
from typing import Dict, List, Optional, Sequence

from rclpy.node import Node

REPO = Path(__file__).resolve().parents[2]
#: The node's name, as the services and topics are named under it.
NODE = '/sik_node'


def params_file() -> Path:
    """``config/panda.yaml`` of the source tree, else of the installed package's share folder."""
    local = REPO / 'config' / 'panda.yaml'
    if local.is_file():
        return local
    from ament_index_python.packages import get_package_share_directory
    return Path(get_package_share_directory('sik_ros')) / 'config' / 'panda.yaml'


def ros_env(domain_id: Optional[int] = None) -> Dict[str, str]:
    """Environment for an isolated ROS graph: a random (or given) domain, discovery on localhost.

    Also exported into this process, so ``rclpy.init`` afterwards joins the same graph.
    """
    domain = domain_id if domain_id is not None else random.SystemRandom().randint(1, 100)
    os.environ['ROS_DOMAIN_ID'] = str(domain)
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    os.environ.setdefault('OMP_NUM_THREADS', '1')
    return dict(os.environ)


def launch_node(model_dir: Optional[str] = None, params: Sequence[str] = (),
                env: Optional[Dict[str, str]] = None, **popen) -> subprocess.Popen:
    """Start ``python -m sik_ros.ros.run`` with ``config/panda.yaml`` and ``-p`` overrides.

    Args:
        model_dir: a bundle directory (None: the bundled model); its own base and tip frames
            are served (the file's Panda frames are overridden).
        params: extra ``name:=value`` parameter overrides.
        env: the process environment (see :func:`ros_env`).
        **popen: passed to :class:`subprocess.Popen` (e.g. ``stdout``).
    """
    cmd = [sys.executable, '-m', 'sik_ros.ros.run', '--ros-args', '--params-file',
           str(params_file())]
    # config/panda.yaml names the Panda's frames and group: another bundle serves its own
    bundle = ([f'model_dir:={model_dir}', "base_frame:=''", "tip_frame:=''", "ik_group:=''"]
              if model_dir else [])
    overrides = bundle + list(params)
    for item in overrides:
        cmd += ['-p', item]
    return subprocess.Popen(cmd, env=env, **popen)


def stop_node(proc: subprocess.Popen, timeout: float = 15.0) -> int:
    """SIGINT the node and wait for it [s]; kill it if it hangs. Returns its exit code."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return proc.returncode


def wait_for_service(node: Node, client, proc: subprocess.Popen, timeout: float) -> bool:
    """Wait until the service is up [s]; False if the node died or the time ran out."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            return False
        if client.wait_for_service(timeout_sec=0.5):
            return True
    return False


def service_up(srv_type, name: str, proc: subprocess.Popen, timeout: float = 90.0) -> bool:
    """Whether ``proc``'s service ``name`` comes up within ``timeout`` [s], seen by a probe node.

    rclpy must be initialised; the probe node is destroyed before returning.
    """
    import rclpy
    node = rclpy.create_node('sik_probe')
    try:
        return wait_for_service(node, node.create_client(srv_type, name), proc, timeout)
    finally:
        node.destroy_node()


def bundle_goals(model_dir: Optional[str]) -> List[str]:
    """Goal kinds (``position``, ``pose``) a bundle has models for; empty if unreadable."""
    if model_dir:
        path = Path(model_dir)
    else:
        from sik_ros.bundles.bundle import BUNDLES  # imported here: it loads torch
        path = BUNDLES / 'panda'
    try:
        return sorted(json.loads((path / 'bundle.json').read_text())['models'])
    except (OSError, ValueError, KeyError, TypeError):
        return []
