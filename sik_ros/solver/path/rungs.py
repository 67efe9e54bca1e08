"""The ladder's data: one planning's fixed parts, its rungs, and the tracks going on."""

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from sik_ros.deadline import Deadline
from sik_ros.kinematics.collision import Obstacle
from sik_ros.kinematics.rotations import rotation_angle
from sik_ros.solver.context import Context, Goal
from sik_ros.solver.path.settings import PathSettings
from sik_ros.solver.refine import Evaluation


@dataclass(frozen=True)
class Plan:
    """What one planning of a path holds fixed.

    Attributes:
        ctx: the solver's parts.
        goals: the waypoints (N).
        obstacles: what no configuration may touch.
        s: the path's settings.
        deadline: when planning stops.
        reach: the chain's curvature bounds (:func:`~sik_ros.solver.path.edges.reach_bounds`).
        turns: (N - 1,) angles between consecutive waypoints' orientations [rad]
            (:func:`waypoint_turns`).
    """

    ctx: Context
    goals: Sequence[Goal]
    obstacles: Sequence[Obstacle]
    s: PathSettings
    deadline: Deadline
    reach: np.ndarray
    turns: np.ndarray


@dataclass(frozen=True)
class Rung:
    """One waypoint's candidates on the ladder; row k of every array belongs to candidate k.

    Attributes:
        q: configurations (M, n) [rad].
        back: the cheapest predecessor of each on the previous rung (M,) (-1: a start).
        cost: the cheapest cost of reaching each (M,) (inf: not reachable).
        p: their tip positions (M, 3) [m]; r: their tip rotations (M, 3, 3).
    """

    q: np.ndarray
    back: np.ndarray
    cost: np.ndarray
    p: np.ndarray
    r: np.ndarray


@dataclass(frozen=True)
class Tracks:
    """The reachable candidates of the last rung, going on to the next waypoint.

    Attributes:
        q: configurations (T, n) [rad].
        rows: their rows on the last rung (T,).
        ev: their evaluation (tip poses, Jacobians and their last change).
        cost: their costs (T,).
    """

    q: np.ndarray
    rows: np.ndarray
    ev: Evaluation
    cost: np.ndarray

    @staticmethod
    def of(rung: Rung, ev: Evaluation) -> 'Tracks':
        """The reachable rows of ``rung`` (``ev``: the evaluation of all its rows)."""
        live = np.isfinite(rung.cost)
        q, rows = rung.q, np.arange(len(live))
        if not live.all():
            q, rows, ev = q[live], rows[live], ev.rows(live)
        return Tracks(q, rows, ev, rung.cost[rows])


def waypoint_turns(goals: Sequence[Goal]) -> np.ndarray:
    """(N - 1,) the angles [rad] between consecutive waypoints' orientations (0: positions)."""
    if len(goals) < 2 or goals[0].rotation is None:
        return np.zeros(max(len(goals) - 1, 0))
    r = np.array([g.rotation for g in goals])
    return rotation_angle(r[:-1], r[1:])
