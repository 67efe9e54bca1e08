"""Solver processes: a process killed while it serves a request is replaced.

The request is answered by another process within its deadline.
"""

import os
import signal
import threading
import time

import numpy as np
import pytest

from sik_ros.kinematics.collision import Obstacle
from sik_ros.serving.pool import SolverPool
from sik_ros.solver import SolverConfig

pytestmark = pytest.mark.e2e


def test_a_request_whose_process_dies_is_retried_on_another(panda, tiny_bundle):
    """A kill -9 of the busy process: another one answers the request within its deadline.

    The pool's log shows the process died while serving; the answer is FK-verified, and the
    pool is back to two living processes.
    """
    logged = []
    pool = SolverPool(tiny_bundle, SolverConfig(), 2, log=lambda level, m: logged.append(m))
    try:
        pos, _ = panda.fk(np.full(panda.dof, 0.3))
        # many obstacles keep a process busy while it is stopped and killed
        rng = np.random.default_rng(0)
        balls = [Obstacle('sphere', (0.01,), position=tuple(rng.uniform(-0.8, 0.8, 3)))
                 for _ in range(6000)]
        pool.configure(max_obstacles=8000)
        out = {}

        def call():
            out['result'] = pool.solve(pos, obstacles=balls, num_solutions=4, timeout=20.0)
        thread = threading.Thread(target=call)
        thread.start()
        busy = []
        deadline = time.monotonic() + 30.0  # a hang guard
        while not busy and time.monotonic() < deadline:  # the process that took the request
            busy = pool.busy_pids
            time.sleep(0.005)
        assert busy, 'no process took the request'
        os.kill(busy[0], signal.SIGSTOP)  # frozen mid-solve, then killed
        os.kill(busy[0], signal.SIGKILL)
        thread.join(60.0)  # a hang guard: the request's timeout is 20 s
        assert not thread.is_alive(), 'the request was not answered'
        assert any('died while serving a request' in m for m in logged), logged
        result = out['result']
        assert result.success, result.message
        for s in result.solutions:
            if s.converged:
                assert np.linalg.norm(panda.fk(s.q)[0] - pos) < 1e-4
        deadline = time.monotonic() + 90.0
        while time.monotonic() < deadline:
            health = pool.health()
            if health.ready == 2 and health.idle == 2:
                break
            time.sleep(0.2)
        assert len(pool.pids) == 2 and busy[0] not in pool.pids
        health = pool.health()
        assert (health.ready, health.idle, health.restarts) == (2, 2, 1), health
    finally:
        pool.close()
