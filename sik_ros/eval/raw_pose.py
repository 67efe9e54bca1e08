"""Raw pose answers of the product: the solver as shipped, and with self-collision unchecked.

The product's figure for raw pose answers is the mean error of the ten answers of
``solve(position, quaternion, num_solutions=10, refine=False)`` at targets uniform in joint space
(``bench/solve.py``'s: seed 2024). The solver ranks answers free of self-collision first; at a
target whose own configuration collides with the arm, the free answers are postures that miss
the pose. :func:`without_self_collision` gives the solver with self-collision unchecked (as the
paper ran), and :func:`raw_pose_study` measures both, every error recomputed by FK. These
answers are selected by their error; the paper's protocol is :mod:`~sik_ros.eval.lookup`'s.
"""

from dataclasses import dataclass
from dataclasses import replace as _replace
from typing import Dict, List

import numpy as np

from sik_ros.eval.markdown import fmt, table
from sik_ros.eval.metrics import orientation_cosine, pin_tips, position_errors
from sik_ros.solver import SelectiveIK

#: Targets and their seed: those of ``bench/solve.py`` (the README's raw figures).
TARGETS, SEED = 100, 2024


class NoSelfCollision:
    """A collision checker that finds no self-collision; everything else is the wrapped one's."""

    def __init__(self, checker):
        self._checker = checker

    def self_collision(self, q: np.ndarray, deadline=None) -> np.ndarray:
        """No configuration collides with itself, (N,) bool."""
        return np.zeros(len(q), dtype=bool)

    def __getattr__(self, name):
        return getattr(self._checker, name)


def without_self_collision(ik: SelectiveIK) -> SelectiveIK:
    """A copy of a solver that does not check self-collision (as the paper ran).

    Obstacles are still checked. The copy has a collision checker of its own (its solver
    context holds the wrapped one); ``ik`` is unchanged.
    """
    out = ik.clone()
    out.checker = NoSelfCollision(out.checker)
    out._ctx = _replace(out._ctx, checker=out.checker)
    return out


@dataclass
class RawPose:
    """Raw pose answers at the targets: per target, the mean over its answers.

    Attributes:
        distance: mean distance error [m], (targets,).
        angle: mean orientation error [rad], (targets,).
        free: whether the target's own configuration is free of self-collision, (targets,).
    """

    distance: np.ndarray
    angle: np.ndarray
    free: np.ndarray


def raw_pose_study(ik: SelectiveIK, targets: int = TARGETS,
                   seed: int = SEED) -> Dict[str, RawPose]:
    """Ten raw answers per pose target, ``shipped`` (free answers first) and ``paper``.

    Targets: FK of configurations uniform in joint space (``seed``).
    """
    robot = ik.robot
    q = np.random.default_rng(seed).uniform(robot.lower, robot.upper, (targets, robot.dof))
    pos, quat = robot.fk_batch(q)
    rot_goal = robot.fk_rot(q)[1]
    free = ~ik.checker.self_collision(q)
    out = {}
    for name, solver in (('shipped', ik), ('unchecked', without_self_collision(ik))):
        dist, angle = np.empty(targets), np.empty(targets)
        for i in range(targets):
            res = solver.solve(pos[i], quat[i], num_solutions=10, refine=False)
            qs = np.array([s.q for s in res.solutions])
            dist[i] = position_errors(robot, qs, pos[i]).mean()
            angle[i] = orientation_cosine(rot_goal[i], pin_tips(robot, qs)[1])[1].mean()
        out[name] = RawPose(dist, angle, free)
    return out


def raw_pose_lines(study: Dict[str, RawPose]) -> List[str]:
    """The report's lines: the mean errors, at all targets, the free ones and the others.

    These answers are the product's: the best of many decoded indices by FK error, so no paper
    figure is set beside them.
    """
    if not study:
        return []
    some = next(iter(study.values()))
    n, n_free = len(some.free), int(some.free.sum())
    lines = ['### Raw pose answers of the product (not the paper\'s protocol)', '',
             f'The same {n} targets (seed {SEED}, as `bench/solve.py`), ten answers '
             'of `solve(position, quaternion, num_solutions=10, refine=False)` each, their mean '
             'distance and orientation errors by FK. A raw call decodes up to 192 indices and '
             'returns those of least error: a figure of the product, selected by error, not '
             'comparable with the paper\'s. As shipped the solver ranks answers free of '
             'self-collision first. '
             f'{n - n_free} of the {n} target configurations collide with the arm itself.', '']
    rows = []
    for name, label in (('shipped', 'as shipped (self-collision ranked)'),
                        ('unchecked', 'self-collision not checked')):
        r = study[name]
        cells = [label]
        for mask in (np.ones(n, dtype=bool), r.free, ~r.free):
            cells.append(f'{fmt(100 * r.distance[mask].mean())} cm, '
                         f'{fmt(np.degrees(r.angle[mask].mean()), 1)}°' if mask.any() else '—')
        rows.append(cells)
    lines += table(['raw pose answers', f'all {n} targets', f'the {n_free} free targets',
                    f'the {n - n_free} self-colliding'], rows)
    return lines + ['']
