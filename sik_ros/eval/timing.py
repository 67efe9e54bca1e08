"""Experiment 2, computing time: wall time per call and per solution of every method."""

from dataclasses import dataclass, replace
import time
from typing import Callable, Dict, Optional, Sequence

import numpy as np

from sik_ros.eval.baselines import Method, multi_solution, single_solution, TracIK
from sik_ros.eval.studies import Progress, table_pool
from sik_ros.solver import SelectiveIK
from sik_ros.solver.codec import decode
from sik_ros.solver.context import Goal


@dataclass
class Timing:
    """Wall time of one method over the timing targets.

    Attributes:
        calls: how many calls were timed.
        median_ms, mean_ms: time per call [ms].
        solutions_per_call: mean number of solutions a call returned.
        per_solution_ms: median over the calls of the time per solution returned [ms] (TRAC-IK:
            the mean time per call over its success rate).
        success: TRAC-IK only: the fraction of calls that found a solution.
    """

    calls: int
    median_ms: float
    mean_ms: float
    solutions_per_call: float
    per_solution_ms: float
    success: Optional[float] = None


def time_calls(fn: Callable[[object], int], items: Sequence,
               progress: Progress = None) -> Timing:
    """Wall time of ``fn(item)`` per item after one warm-up call; ``fn`` returns a count."""
    fn(items[0])
    times, counts = [], []
    for item in items:
        t0 = time.perf_counter()
        counts.append(fn(item))
        times.append(time.perf_counter() - t0)
        if progress:
            progress(1)
    times, counts = np.array(times), np.array(counts, dtype=float)
    per_solution = times / np.maximum(counts, 1)
    return Timing(len(items), 1e3 * float(np.median(times)), 1e3 * float(times.mean()),
                  float(counts.mean()), 1e3 * float(np.median(per_solution)))


def timing_study(ik: SelectiveIK, baselines: Dict[str, Method], positions: np.ndarray,
                 quats: np.ndarray, tracik: Optional[TracIK] = None, seed: int = 0,
                 progress: Progress = None) -> Dict[str, Timing]:
    """Experiment 2: wall time per call and per solution of every method, in one run.

    SIK/PSIK solutions count the solutions a call returns; the single-solution methods return
    one (TRAC-IK: one when it succeeds within its timeout, from a random seed).

    Args:
        ik: the SIK solver.
        baselines: the other methods (see :func:`sik_ros.eval.baselines.load_baselines`).
        positions: target positions (N, 3) [m].
        quats: target orientations (N, 4), x y z w (TRAC-IK solves the full pose).
        tracik: TRAC-IK, or None to leave it out.
        seed: seed of TRAC-IK's random start postures.
        progress: called per timed call.

    Returns:
        ``{key: Timing}``; keys ``<solver>_decode`` (one decoder forward pass),
        ``<solver>_<raw|refined>_<1|10>`` (``solve`` for 1 or 10 solutions), the single-solution
        baselines by name and ``tracik``.
    """
    out = {}
    items = list(np.asarray(positions, dtype=float))
    for name, s in multi_solution(ik, baselines).items():
        z0 = table_pool(s.models['position'].table, items[0], 1)[:1]
        out[f'{name}_decode'] = time_calls(
            lambda p, s=s, z0=z0: len(decode(s.context, Goal(p), z0)), items, progress)
        for num in (1, 10):
            for refine in (False, True):
                key = f'{name}_{"refined" if refine else "raw"}_{num}'
                out[key] = time_calls(
                    lambda p, s=s, n=num, r=refine: len(
                        s.solve(p, num_solutions=n, refine=r).solutions), items, progress)
    for name, b in single_solution(baselines).items():
        out[name] = time_calls(lambda p, b=b: len(b.predict(p[None])), items, progress)
    if tracik is not None:
        rng = np.random.default_rng(seed)
        seeds = rng.uniform(ik.robot.lower, ik.robot.upper, (len(items), ik.robot.dof))
        ok = []

        def run(i: int) -> int:
            good, _ = tracik.solve(items[i], quats[i], seeds[i])
            ok.append(good)
            return int(good)
        rec = time_calls(run, list(range(len(items))), progress)
        success = float(np.mean(ok[1:]))
        # time spent per solution found: all the calls' time over the successful ones
        out['tracik'] = replace(rec, success=success,
                                per_solution_ms=rec.mean_ms / max(success, 1e-9))
    return out
