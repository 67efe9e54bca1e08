"""Many targets on several cores: :meth:`SelectiveIK.solve_batch` in worker processes.

A solve runs numba kernels between Python stages that hold the GIL, so threads of one process
take turns and a second core stays idle; the targets go to worker processes instead. Each
worker holds one solver for the whole batch: a forked worker clones the caller's (its tables
and networks shared with the parent, nothing loaded again), a spawned one (where ``fork`` is
unavailable or unsafe: a process running ``rclpy``, whose middleware threads a fork would not
carry) loads the bundle once; before a fork the caller's objects are frozen out of the garbage
collector's reach (``gc.freeze``), so that the workers' collections do not copy the pages they
share with it. The targets travel in chunks of consecutive rows and come back, packed into a few
arrays per chunk, in target order; every row is checked before any is solved.
"""

import contextlib
import functools
import gc
import multiprocessing
import os
import sys
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from sik_ros import errors
from sik_ros.errors import InvalidArgument, SikError
from sik_ros.solver.codec import encode
from sik_ros.solver.inputs import check_arrays, check_goal, check_seed
from sik_ros.solver.results import IKResult, PendingIndices, Solution

__all__ = ['check_rows', 'check_workers', 'default_workers', 'single_threaded',
           'solve_chunk_with', 'solve_rows']

#: Chunks per worker: small enough to even out slow targets, large enough to pay the pipe.
CHUNKS_PER_WORKER = 32
#: Fewest targets per worker that are worth a process (below: solved in this process).
MIN_ROWS_PER_WORKER = 16

#: The worker process's solver (set by :func:`_start`), and the caller's, inherited by fork.
_SOLVER = None
_INHERITED = None


def default_workers() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def check_rows(ik, positions, orientations, seed):
    """The batch's arrays, every row checked as :meth:`SelectiveIK.solve` checks its target.

    Args:
        ik: the solver (its goal kinds and robot).
        positions: targets (N, 3) [m].
        orientations: None, or quaternions (N, 4) x y z w.
        seed: None, one configuration (n,) for every target, or one per target (N, n) [rad].

    Returns:
        positions (N, 3), orientations (N, 4) or None, and the seeds: None, or (N, n).

    Raises:
        InvalidGoal, InvalidSeed: the error :meth:`solve` raises for the bad row, its message
            starting with ``target i:`` and its ``row`` attribute ``i``; or the arrays'
            shapes.
    """
    pos, quat = check_arrays(positions, orientations)
    for i in range(len(pos)):
        try:
            check_goal(pos[i], None if quat is None else quat[i], ik.goals)
        except SikError as exc:
            raise _for_row(exc, i) from exc
    if seed is None:
        return pos, quat, None
    try:
        per_row = np.ndim(seed) == 2
    except (TypeError, ValueError):  # ragged: check_seed says what is wrong
        per_row = False
    if not per_row:
        return pos, quat, np.repeat(check_seed(ik.robot, seed)[None], len(pos), 0)
    if len(seed) != len(pos):
        raise errors.InvalidSeed(f'seed must be one configuration or one per target '
                                 f'({len(pos)} rows); got {len(seed)} rows')
    seeds = []
    for i, row in enumerate(seed):
        try:
            seeds.append(check_seed(ik.robot, row))
        except SikError as exc:
            raise _for_row(exc, i) from exc
    return pos, quat, np.array(seeds)


def _for_row(exc: SikError, row: int) -> SikError:
    """``exc``'s class, its message prefixed by the row (attributes kept)."""
    new = type(exc).__new__(type(exc))
    new.__dict__.update(exc.__dict__)
    Exception.__init__(new, f'target {row}: {exc}')
    new.row = row
    return new


def solve_rows(ik, pos: np.ndarray, quat: Optional[np.ndarray], seeds: Optional[np.ndarray],
               kwargs: Dict[str, Any], workers: int, progress: bool,
               executor=None) -> List[IKResult]:
    """Each row's :meth:`SelectiveIK.solve`, on ``workers`` processes or ``executor``, in order.

    ``executor``: None, or one with ``workers`` and ``solve_chunks(ik, chunks, kwargs)``
    (:class:`~sik_ros.solver.cluster.RayExecutor`).
    """
    n = len(pos)
    bar = _bar(n, progress)
    try:
        if executor is not None:
            if not _picklable(kwargs):
                raise InvalidArgument('an executor\'s workers need keywords that can be '
                                      'pickled (an objective of a lambda cannot)')
            chunks = _chunks(pos, quat, seeds, executor.workers,
                             getattr(executor, 'chunks_per_worker', CHUNKS_PER_WORKER))
            return _gathered(ik, pos, quat, executor.solve_chunks(ik, chunks, kwargs), bar)
        workers = max(1, min(int(workers), n // MIN_ROWS_PER_WORKER))
        context = _start_method(ik)
        if workers == 1 or context is None or not _picklable(kwargs):
            out = []
            for i in range(n):
                out.append(_solve_one(ik, pos, quat, seeds, i, kwargs))
                bar.update(1)
            return out
        return _on_processes(ik, pos, quat, seeds, kwargs, workers, context, bar)
    finally:
        bar.close()


def _chunks(pos, quat, seeds, workers: int,
            per_worker: int = CHUNKS_PER_WORKER) -> List[Tuple[int, Any, Any, Any]]:
    """The batch in chunks of consecutive rows: ``(start, pos, quat, seeds)`` each."""
    n = len(pos)
    size = max(1, -(-n // (workers * per_worker)))
    return [(a, pos[a:a + size], None if quat is None else quat[a:a + size],
             None if seeds is None else seeds[a:a + size]) for a in range(0, n, size)]


def _gathered(ik, pos, quat, replies, bar) -> List[IKResult]:
    """The answers of the chunks' ``(start, reply)`` (in any order), in row order."""
    results: List[Optional[IKResult]] = [None] * len(pos)
    for start, reply in replies:
        answers, lazy = _checked(reply)
        _pending_again(ik, pos, quat, start, answers, lazy)
        results[start:start + len(answers)] = answers
        bar.update(len(answers))
    return results


def _picklable(value) -> bool:
    """Whether ``value`` can travel to a worker (an objective of a lambda cannot)."""
    import pickle
    try:
        pickle.dumps(value)
        return True
    except Exception:  # pickling raises many types
        return False


def _solve_one(ik, pos, quat, seeds, i: int, kwargs) -> IKResult:
    return ik.solve(pos[i], None if quat is None else quat[i],
                    seed=None if seeds is None else seeds[i], **kwargs)


def _start_method(ik) -> Optional[str]:
    """``fork`` where it is safe, else ``spawn`` where the bundle can be loaded, else None."""
    methods = multiprocessing.get_all_start_methods()
    if 'fork' in methods and 'rclpy' not in sys.modules:
        return 'fork'
    return 'spawn' if ik.bundle is not None else None


def _on_processes(ik, pos, quat, seeds, kwargs, workers: int, method: str,
                  bar) -> List[IKResult]:
    from concurrent.futures import as_completed, ProcessPoolExecutor
    global _INHERITED
    if method == 'fork':
        _INHERITED, init = ik, (None, None, None)
    else:
        init = (str(ik.bundle), _config_fields(ik.config), type(ik))
    if method == 'fork':
        # the caller's objects in the permanent generation: a worker's garbage collections
        # then leave the pages it shares with the caller alone (no copy-on-write of them)
        gc.freeze()
    try:
        pool = ProcessPoolExecutor(workers, multiprocessing.get_context(method),
                                   initializer=_start, initargs=init)
        with _stopped_at_once(pool):
            futures = [pool.submit(_solve_chunk, *chunk, kwargs)
                       for chunk in _chunks(pos, quat, seeds, workers)]
            return _gathered(ik, pos, quat, (f.result() for f in as_completed(futures)), bar)
    finally:
        _INHERITED = None
        if method == 'fork':
            gc.unfreeze()


@contextlib.contextmanager
def _stopped_at_once(pool):
    """The pool shut down when the block ends; its workers ended at once if it raised.

    A Ctrl-C of the caller does not wait for the chunks under way (the workers ignore SIGINT).
    """
    try:
        yield pool
    except BaseException:
        processes = list(getattr(pool, '_processes', {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            process.terminate()
        raise
    pool.shutdown(wait=True)


def _config_fields(config) -> Dict[str, Any]:
    from dataclasses import asdict
    return asdict(config)


def single_threaded() -> None:
    """One thread for BLAS and torch in this (worker) process."""
    from threadpoolctl import threadpool_limits
    threadpool_limits(1)
    torch = sys.modules.get('torch')
    if torch is not None:
        torch.set_num_threads(1)


def _start(bundle: Optional[str], config: Optional[Dict[str, Any]], solver_class) -> None:
    """A worker's start: one thread for BLAS and torch, then its solver, once.

    ``solver_class`` (:class:`SelectiveIK`, passed by the caller) loads ``bundle``.
    """
    global _SOLVER
    import signal
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the caller stops the batch
    single_threaded()
    if bundle is None:
        _SOLVER = _INHERITED.clone()
    else:
        from sik_ros.solver.config import SolverConfig
        _SOLVER = solver_class.load(bundle, SolverConfig(**config))


def _solve_chunk(start: int, pos, quat, seeds, kwargs) -> Tuple[int, Tuple[str, Any]]:
    """The worker's answers to the chunk at ``start`` (:func:`solve_chunk_with`)."""
    return start, solve_chunk_with(_SOLVER, pos, quat, seeds, kwargs)


def solve_chunk_with(solver, pos, quat, seeds, kwargs) -> Tuple[str, Any]:
    """A chunk's answers, packed into arrays (:func:`pack`), or the error that stopped it.

    A posture index not yet encoded stays so (encoding costs more than the solve): the
    solution travels without it and the caller encodes it when it is first read.
    """
    try:
        return 'ok', pack([_solve_one(solver, pos, quat, seeds, i, kwargs)
                           for i in range(len(pos))])
    except SikError as exc:
        return 'error', (type(exc).__name__, str(exc))


#: The per-solution fields that travel as one array each (:func:`pack`), in order.
_FLOATS = ('position_error', 'orientation_error', 'score', 'min_obstacle_distance')
_FLAGS = ('self_collision', 'converged')
_INTS = ('tier', 'family')


def pack(results: List[IKResult]) -> Dict[str, Any]:
    """A chunk's answers as a few arrays, made again by :func:`unpack`.

    They cross the pipe far cheaper than thousands of pickled objects would.
    The solutions' rows are stacked in answer order; ``lazy`` marks those whose posture index
    was not yet encoded (travelled as NaN).
    """
    sols = [s for res in results for s in res.solutions]
    lazy = np.array([s.__dict__.get('_pending') is not None for s in sols], dtype=bool)
    out: Dict[str, Any] = dict(
        head=[(r.success, r.goal, r.timed_out, r.elapsed, r.message, r.num_families,
               len(r.solutions)) for r in results],
        lazy=lazy)
    if sols:
        out['q'] = np.array([s.q for s in sols])
        widths = [len(s.__dict__['_posture_index']) for s, p in zip(sols, lazy) if not p]
        z = np.full((len(sols), widths[0] if widths else 0), np.nan)
        for k, (s, pending) in enumerate(zip(sols, lazy)):
            if not pending:
                z[k] = s.__dict__['_posture_index']
        out['z'] = z
        for name in _FLOATS:
            out[name] = np.array([getattr(s, name) for s in sols], dtype=float)
        for name in _FLAGS:
            out[name] = np.array([getattr(s, name) for s in sols], dtype=bool)
        for name in _INTS:
            out[name] = np.array([getattr(s, name) for s in sols], dtype=np.int64)
    return out


def unpack(packed: Dict[str, Any]) -> Tuple[List[IKResult], List[List[int]]]:
    """:func:`pack`'s answers made again, and per answer its solutions without an index."""
    results, lazy, k = [], [], 0
    flags = packed['lazy']
    for success, goal, timed_out, elapsed, message, families, count in packed['head']:
        sols, rows = [], []
        for j in range(count):
            sol = Solution(packed['q'][k].copy(), float(packed['position_error'][k]),
                           float(packed['orientation_error'][k]),
                           None if flags[k] else packed['z'][k].copy(),
                           score=float(packed['score'][k]),
                           min_obstacle_distance=float(packed['min_obstacle_distance'][k]),
                           self_collision=bool(packed['self_collision'][k]),
                           converged=bool(packed['converged'][k]),
                           tier=int(packed['tier'][k]), family=int(packed['family'][k]))
            if flags[k]:
                rows.append(j)
            sols.append(sol)
            k += 1
        results.append(IKResult(bool(success), sols, goal, bool(timed_out), float(elapsed),
                                message, int(families)))
        lazy.append(rows)
    return results, lazy


def _pending_again(ik, pos, quat, start: int, out: List[IKResult],
                   lazy: List[List[int]]) -> None:
    """The caller's encoder for the solutions that travelled without their posture index."""
    for k, (res, rows) in enumerate(zip(out, lazy)):
        if rows:
            i = start + k
            goal = check_goal(pos[i], None if quat is None else quat[i], ik.goals)
            PendingIndices([res.solutions[j] for j in rows],
                           functools.partial(encode, ik.context, goal))


def _checked(reply: Tuple[str, Any]):
    kind, value = reply
    if kind == 'ok':
        return unpack(value)
    name, message = value
    cls = getattr(errors, name, None)
    cls = cls if isinstance(cls, type) and issubclass(cls, SikError) else SikError
    exc = cls.__new__(cls)
    Exception.__init__(exc, message)
    raise exc


def _bar(total: int, show: bool):
    if show:
        from tqdm import tqdm
        return tqdm(total=total, unit='target', desc='solve_batch')
    return _NoBar()


class _NoBar:
    def update(self, _n: int) -> None:
        """Nothing to show."""

    def close(self) -> None:
        """Nothing to close."""


def check_workers(workers) -> int:
    """``workers`` as a count >= 1 (None: every core).

    Raises:
        InvalidArgument: not a positive integer.
    """
    if workers is None:
        return default_workers()
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise InvalidArgument(f'workers must be a positive integer or None; got {workers!r}')
    return int(workers)
