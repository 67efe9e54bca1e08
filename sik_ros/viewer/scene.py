"""What the viewer shows for a target, without the browser: solutions, their table, the layout.

Everything here is plain data computed from the solver; :mod:`sik_ros.viewer.app` draws it.
"""

from dataclasses import dataclass, field
import math
from typing import List, Optional, Sequence, Tuple

import numpy as np

from sik_ros.kinematics.collision import Obstacle
from sik_ros.solver import IKResult, SelectiveIK
from sik_ros.solver.path import PathResult
from sik_ros.solver.results import family_label

#: Colours of the ranking tiers (0 free and exact, 1 free and inexact, 2 colliding) [RGB].
TIER_COLORS = ((40, 150, 85), (230, 140, 20), (210, 40, 40))
#: The best solution's colour, drawn apart from the others of its tier [RGB].
BEST_COLOR = (30, 90, 210)
#: Postures per row when shown side by side.
COLUMNS = 4


@dataclass
class Goal:
    """A target for the solver.

    Attributes:
        position: (3,) in the base frame [m].
        orientation: quaternion x y z w, or None for a position goal.
        num_solutions: how many ranked solutions to ask for.
        obstacles: obstacles in the base frame.
    """

    position: np.ndarray
    orientation: Optional[np.ndarray] = None
    num_solutions: int = 16
    obstacles: List[Obstacle] = field(default_factory=list)


def solve_goal(ik: SelectiveIK, goal: Goal, seed: Optional[np.ndarray] = None) -> IKResult:
    """The solver's ranked answer for ``goal``."""
    return ik.solve(goal.position, orientation=goal.orientation,
                    num_solutions=goal.num_solutions, seed=seed, obstacles=goal.obstacles)


def solution_colors(result: IKResult) -> np.ndarray:
    """(k, 3) RGB per solution: the best in blue, the rest by their ranking tier."""
    colors = [TIER_COLORS[min(s.tier, 2)] for s in result.solutions]
    if colors and result.solutions[0].tier == 0:
        colors[0] = BEST_COLOR
    return np.array(colors, dtype=np.uint8).reshape(-1, 3)


def grid_offsets(count: int, spacing: float) -> np.ndarray:
    """Offsets (count, 3) [m] that lay postures side by side, ``COLUMNS`` to a row.

    The first is at the origin; rows go along -x, columns along +y.
    """
    k = np.arange(count)
    return np.stack([-(k // COLUMNS) * spacing, (k % COLUMNS) * spacing, np.zeros(count)], 1)


def reach(ik: SelectiveIK) -> float:
    """The arm's reach: the sum of its link offsets along the chain [m]."""
    return float(np.linalg.norm(ik.robot.chain.joint_translations, axis=1).sum())


def start_target(ik: SelectiveIK) -> Tuple[np.ndarray, np.ndarray]:
    """A reachable first target: the tip at mid-range joint values (position, x y z w)."""
    q = 0.5 * (ik.robot.lower + ik.robot.upper)
    position, quaternion = ik.fk(q)
    return np.asarray(position, float), np.asarray(quaternion, float)


def _fmt(value: float, scale: float, digits: int) -> str:
    return '∞' if not math.isfinite(value) else f'{value * scale:.{digits}f}'


def table(result: IKResult, selected: Optional[int] = None) -> str:
    """A Markdown table of the ranked solutions: errors, clearance, score, tier, family."""
    if not result.solutions:
        return '**No solution.**'
    head = ('| # | pos err [mm] | rot err [deg] | clearance [m] | score | tier | family |\n'
            '|---|---|---|---|---|---|---|\n')
    rows = []
    for i, s in enumerate(result.solutions):
        mark = f'**{i + 1}**' if i == selected else str(i + 1)
        rows.append(f'| {mark} | {_fmt(s.position_error, 1e3, 3)} | '
                    f'{_fmt(s.orientation_error, 180 / math.pi, 3)} | '
                    f'{_fmt(s.min_obstacle_distance, 1, 3)} | {s.score:.4g} | {s.tier} | '
                    f'{family_label(s)} |')
    status = 'success' if result.success else 'no exact solution'
    return (f'{len(result.solutions)} solutions ({status}), {result.num_families} '
            f"famil{'y' if result.num_families == 1 else 'ies'} found\n\n" + head
            + '\n'.join(rows))


def joint_text(names: Sequence[str], q: np.ndarray) -> str:
    """A solution's joint values as a Markdown list [rad]."""
    return '\n'.join(f'- `{n}`: {v:+.4f}' for n, v in zip(names, q))


def line_path(start: np.ndarray, end: np.ndarray, orientation: Optional[np.ndarray],
              waypoints: int) -> Tuple[np.ndarray, Optional[np.ndarray]]:
    """Waypoints on the straight line from ``start`` to ``end`` [m], the orientation held."""
    t = np.linspace(0.0, 1.0, max(2, int(waypoints)))[:, None]
    positions = (1 - t) * np.asarray(start, float) + t * np.asarray(end, float)
    if orientation is None:
        return positions, None
    return positions, np.repeat(np.asarray(orientation, float)[None], len(positions), 0)


def solve_line(ik: SelectiveIK, goal: Goal, end: np.ndarray, waypoints: int,
               seed: Optional[np.ndarray]) -> PathResult:
    """The ranked joint paths along the line from the goal's position to ``end``."""
    positions, orientations = line_path(goal.position, end, goal.orientation, waypoints)
    return ik.solve_path(positions, orientations, seed=seed, obstacles=goal.obstacles)
