"""What sets PSIK's posture indices apart from SIK's: their range, and interpolation between them.

The paper's case for PSIK (its Discussion): SIK's indices are arbitrary numbers, PSIK's are
normalised (bounded in a known range), and the index between two indices decodes to a posture
between theirs. :func:`index_properties` measures both on a solver's table: the spread of each
element over the table, and, at targets, pairs of the table's indices decoded with their
midpoint (the distance error at the endpoints and at the midpoint, and how far the midpoint's
posture lies from halfway between the endpoints' postures).
"""

from dataclasses import dataclass
from typing import Dict, List

import numpy as np

from sik_ros.eval.markdown import fmt, table
from sik_ros.eval.metrics import position_errors
from sik_ros.eval.paper import NAMES
from sik_ros.solver import SelectiveIK
from sik_ros.solver.codec import decode
from sik_ros.solver.context import Goal

#: Pairs of indices decoded per target.
PAIRS = 10
#: Postures closer than this [rad] (joint-space norm) are one posture.
SAME_POSTURE = 1e-4


@dataclass
class IndexProperties:
    """One solver's posture indices.

    Attributes:
        mean, std: per element over the table's indices (latent,).
        low, high: per element, the 1st and 99th percentiles over the table (latent,).
        targets: targets the pairs were decoded at.
        pairs: ``{kind: Midpoints}`` for ``random`` pairs of the pool near each target and
            ``adjacent`` ones (an index and the nearest other index of the pool).
    """

    mean: np.ndarray
    std: np.ndarray
    low: np.ndarray
    high: np.ndarray
    targets: int
    pairs: Dict[str, 'Midpoints']


@dataclass
class Midpoints:
    """Pairs of indices decoded at their targets with their midpoints.

    Attributes:
        endpoint_err: distance errors of the pairs' own indices decoded [m], (2 * pairs,).
        midpoint_err: distance errors of the midpoints decoded [m], (pairs,).
        detour: per pair, the distance of the midpoint's posture from halfway between the
            endpoints' postures, over the distance between the endpoints' postures (joint space,
            [rad] / [rad]); 0 is a straight interpolation, (pairs,).
    """

    endpoint_err: np.ndarray
    midpoint_err: np.ndarray
    detour: np.ndarray


def index_properties(ik: SelectiveIK, targets: np.ndarray, pairs: int = PAIRS,
                     seed: int = 0) -> IndexProperties:
    """Spread of a solver's position-table indices, and decoded midpoints of pairs of them.

    At each target [m], ``pairs`` indices are drawn from the table's indices near it (the pool
    a raw solve decodes from), each paired with another drawn at random and with its nearest
    other index of the pool, and decoded at the target with their midpoints.
    """
    table = ik.models['position'].table
    z_all = np.asarray(table.indices, dtype=float)
    rng = np.random.default_rng(seed)
    found: Dict[str, List[Midpoints]] = {'random': [], 'adjacent': []}
    used = 0
    for p in np.asarray(targets, dtype=float):
        pool = np.asarray(table.indices[table.rows_near(p, table.pool_cells(ik.config.k_cells))],
                          dtype=float)
        if len(pool) < 2:
            continue
        used += 1
        a = rng.choice(len(pool), pairs, replace=len(pool) < pairs)
        other = (a + rng.integers(1, len(pool), pairs)) % len(pool)
        dist = np.linalg.norm(pool[a][:, None] - pool[None], axis=2)
        dist[np.arange(pairs), a] = np.inf
        for kind, b in (('random', other), ('adjacent', dist.argmin(axis=1))):
            found[kind].append(midpoints(ik, p, pool[a], pool[b]))
    joined = {kind: Midpoints(*(np.concatenate([getattr(m, f) for m in ms]) for f in
                                ('endpoint_err', 'midpoint_err', 'detour')))
              for kind, ms in found.items() if ms}
    return IndexProperties(z_all.mean(0), z_all.std(0), np.percentile(z_all, 1, axis=0),
                           np.percentile(z_all, 99, axis=0), used, joined)


def midpoints(ik: SelectiveIK, position: np.ndarray, za: np.ndarray,
              zb: np.ndarray) -> Midpoints:
    """Pairs of indices (k, latent) and their midpoints decoded at a position [m]."""
    k = len(za)
    q = decode(ik.context, Goal(position), np.concatenate([za, zb, 0.5 * (za + zb)]))
    qa, qb, qm = q[:k], q[k:2 * k], q[2 * k:]
    gap = np.linalg.norm(qa - qb, axis=1)
    off = np.linalg.norm(qm - 0.5 * (qa + qb), axis=1)
    # one posture twice (a pair of equal indices) is no detour, whatever the rounding
    detour = np.where(gap > SAME_POSTURE, off / np.maximum(gap, SAME_POSTURE), 0.0)
    return Midpoints(position_errors(ik.robot, np.concatenate([qa, qb]), position),
                     position_errors(ik.robot, qm, position), detour)


def index_properties_lines(props: dict) -> List[str]:
    """The report's subsection: ``props`` is ``{solver name: IndexProperties}``."""
    if not props:
        return []
    lines = ['### The indices of SIK and PSIK: range and interpolation', '',
             'The paper (Discussion): SIK\'s indices are arbitrary numbers, PSIK\'s are '
             'normalised, bounded in a known range, and an index between two indices gives a '
             'posture between theirs. Per element over each position table: mean, standard '
             'deviation and the 1st to 99th percentile:', '']
    rows = []
    for name, pr in props.items():
        rng = ', '.join(f'{lo:+.2f} to {hi:+.2f}' for lo, hi in zip(pr.low, pr.high))
        rows.append([NAMES[name], ', '.join(f'{v:+.2f}' for v in pr.mean),
                     ', '.join(f'{v:.2f}' for v in pr.std), rng])
    lines += table(['model', 'mean per element', 'std per element', '1st-99th percentile'],
                   rows)
    lines += ['', f'At the first workspace targets, {PAIRS} indices of the table near each '
              'target, each paired with another at random and with its nearest other index '
              '(adjacent), decoded there with the midpoint of the pair: the distance error at '
              'the endpoints and at the midpoint, and the detour, how far the midpoint\'s '
              'posture lies from halfway between the endpoints\' postures over the distance '
              'between them (0: a straight line in joint space).', '']
    rows = []
    for name, pr in props.items():
        for kind, m in pr.pairs.items():
            rows.append([NAMES[name], kind, pr.targets, fmt(100 * m.endpoint_err.mean()),
                         fmt(100 * m.midpoint_err.mean()), fmt(float(np.median(m.detour)))])
    lines += table(['model', 'pairs', 'targets', 'endpoints [cm]', 'midpoints [cm]',
                    'detour (median)'], rows)
    return lines + ['']
