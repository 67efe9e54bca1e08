"""The node's solvers take settings when they change, once per instance, not per request."""

import numpy as np

from sik_ros.serving.solvers import LocalSolvers
from sik_ros.solver import SelectiveIK


def test_local_solvers_take_changed_settings_once_before_their_next_request(monkeypatch):
    """A clone is configured on its first request after a change, and not on later ones."""
    ik = SelectiveIK.load('panda')
    solvers = LocalSolvers(ik, clones=1)
    calls = []
    real = SelectiveIK.configure

    def counted(self, **changes):
        calls.append(changes)
        return real(self, **changes)
    monkeypatch.setattr(SelectiveIK, 'configure', counted)
    pos, _ = ik.fk(0.5 * (ik.robot.lower + ik.robot.upper))
    solvers.solve(pos, num_solutions=2)
    assert calls == []  # the clones start with the loaded instance's settings
    solvers.configure(position_tolerance=2e-4)
    solvers.configure(position_tolerance=2e-4)  # the same values: no new version
    for _ in range(3):
        res = solvers.solve(pos, num_solutions=2)
    assert calls == [{'position_tolerance': 2e-4}]
    assert res.success and all(s.position_error < 2e-4 for s in res.solutions)
    solvers.configure(orientation_tolerance=2e-3)
    solvers.solve(pos, num_solutions=2)
    assert calls[-1] == {'position_tolerance': 2e-4, 'orientation_tolerance': 2e-3}
    assert len(calls) == 2
    assert np.isfinite(res.solutions[0].q).all()
