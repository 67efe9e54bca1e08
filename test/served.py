"""A shared check for tests whose model or bundle must answer: what it answered is true."""

import numpy as np
import pytest


def check_served(robot, res, position) -> int:
    """Every solution within the limits, its reported position error its FK error [m].

    Returns how many solutions were checked (at least one: an empty answer fails).
    """
    assert res.solutions, res.message
    for s in res.solutions:
        assert np.all(s.q >= robot.lower) and np.all(s.q <= robot.upper)
        p, _ = robot.fk(s.q)
        assert s.position_error == pytest.approx(np.linalg.norm(p - position), abs=1e-9)
        assert np.isfinite(s.position_error)
    return len(res.solutions)
