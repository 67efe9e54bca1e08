"""The node's solvers: clones in the node's process, or solver processes with a local fallback.

With ``solver_processes: 0`` each executor thread borrows a :meth:`SelectiveIK.clone` (its own
Pinocchio and coal data) from a pool of clones, so parallel requests never share mutable state.
With solver processes, requests and paths go to a :class:`~sik_ros.serving.pool.SolverPool`;
while the pool is short of a process (one is being restarted) and none is idle, a request is
solved by the node's own solver instead of waiting for a process that may be slow to come back;
so is a request whose process died while serving it and whose retry found none.
"""

from contextlib import contextmanager
import logging
import queue
import threading
import time
from typing import Any, Callable, Dict, Iterator, Optional

from sik_ros.errors import SolverCrashed, SolverTimeout, SolverUnavailable
from sik_ros.solver import IKResult, PathResult, SelectiveIK

#: ``log(level, message)`` with :mod:`logging` levels.
Log = Callable[[int, str], None]


class NodeSolvers:
    """Where the node's requests are solved; safe to call from every executor thread."""

    def __init__(self, ik: SelectiveIK, processes: int, clones: int, log: Log):
        """Start the solver processes, or make and warm up ``clones`` clones of ``ik``.

        Args:
            ik: the loaded solver (the clones and processes are made from it).
            processes: solver processes (0: clones in this process).
            clones: clones to make when ``processes`` is 0 (one per executor thread).
            log: where lost and restored capacity is reported.

        Raises:
            SikError: a solver process could not start.
        """
        from sik_ros.serving.pool import SolverPool  # only with processes: multiprocessing
        self._ik = ik
        self._log = log
        self._clones: 'queue.LifoQueue[SelectiveIK]' = queue.LifoQueue()
        self._own = threading.Lock()  # the node's own solver, for the fallback
        self._pool: Optional[SolverPool] = None
        self.fallbacks = 0
        self.warm_up_seconds = 0.0
        if processes > 0:
            self._pool = SolverPool(ik.bundle, ik.config, processes, log=log)
            self.warm_up_seconds = ik.warm_up()
        else:
            for _ in range(clones):
                clone = ik.clone()
                self.warm_up_seconds += clone.warm_up()
                self._clones.put(clone)

    @property
    def pool(self):
        """The :class:`~sik_ros.serving.pool.SolverPool`, or None without solver processes."""
        return self._pool

    def health(self) -> Optional[Any]:
        """The solver processes' :class:`~sik_ros.serving.pool.PoolHealth` (None without)."""
        return None if self._pool is None else self._pool.health()

    def solve(self, settings: Dict[str, Any], *args, **kwargs) -> IKResult:
        """:meth:`SelectiveIK.solve` with the config fields ``settings``."""
        return self._call('solve', settings, args, kwargs)

    def solve_path(self, settings: Dict[str, Any], *args, **kwargs) -> PathResult:
        """:meth:`SelectiveIK.solve_path` with the config fields ``settings``."""
        return self._call('solve_path', settings, args, kwargs)

    def _call(self, method: str, settings: Dict[str, Any], args, kwargs):
        if self._pool is not None:
            start = time.monotonic()
            try:
                return self._pool.call(method, settings, *args, **kwargs)
            except SolverTimeout:
                raise
            except (SolverUnavailable, SolverCrashed):
                # a process is missing, or died with the request: the node solves it itself,
                # in what is left of the request's time
                self.fallbacks += 1
                if kwargs.get('timeout') is not None:
                    left = kwargs['timeout'] - (time.monotonic() - start)
                    if left <= 0:
                        raise SolverTimeout('the solver processes could not serve this '
                                            'request within its timeout') from None
                    kwargs = dict(kwargs, timeout=left)
        with self._borrow(settings, kwargs.get('timeout')) as ik:
            return getattr(ik, method)(*args, **kwargs)

    @contextmanager
    def _borrow(self, settings: Dict[str, Any], timeout: Optional[float]
                ) -> Iterator[SelectiveIK]:
        """A solver of this process with ``settings``: a clone, or the node's own (fallback).

        Raises:
            SolverTimeout: the node's own solver stayed busy for the whole ``timeout``.
        """
        if self._pool is None:
            ik = self._clones.get()
            try:
                _configure(ik, settings)
                yield ik
            finally:
                self._clones.put(ik)
            return
        start = time.monotonic()
        if not self._own.acquire(timeout=-1 if timeout is None else timeout):
            raise SolverTimeout('every solver was busy for the request\'s whole timeout '
                                f'({time.monotonic() - start:.2f} s)')
        try:
            _configure(self._ik, settings)
            yield self._ik
        finally:
            self._own.release()

    def close(self) -> None:
        """Stop the solver processes (idempotent)."""
        if self._pool is not None:
            self._pool.close()
            self._log(logging.DEBUG, 'solver processes stopped')


def _configure(ik: SelectiveIK, settings: Dict[str, Any]) -> None:
    """Give ``ik`` the config fields ``settings`` (in place; nothing when they are in force)."""
    if any(getattr(ik.config, k) != v for k, v in settings.items()):
        ik.configure(**settings)  # keeps its Pinocchio and coal data
