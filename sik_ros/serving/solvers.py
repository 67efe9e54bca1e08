"""The node's solvers: one :class:`Solver` to call, local clones or solver processes.

:func:`make_solvers` gives either

- :class:`LocalSolvers` (``solver_processes: 0``): each executor thread borrows a
  :meth:`SelectiveIK.clone` (its own Pinocchio and coal data) from a pool of clones, so
  parallel requests never share mutable state;
- :class:`PooledSolvers`: requests and paths go to a :class:`~sik_ros.serving.pool.SolverPool`;
  while the pool is short of a process (one is being restarted) and none is idle, a request
  is solved by the node's own solver instead of waiting for a process that may be slow to
  come back; so is a request whose process died while serving it and whose retry found none.

Settings (the :class:`~sik_ros.solver.SolverConfig` fields a server sets from its parameters)
are pushed with :meth:`Solver.configure` when they change, not sent with every request: each
clone, process and the node's own solver takes them before its next request, once.
"""

from contextlib import contextmanager
from dataclasses import dataclass
import logging
import queue
import threading
import time
from typing import Any, Callable, Dict, Iterator, Optional, Protocol

from sik_ros.errors import SolverCrashed, SolverTimeout, SolverUnavailable
from sik_ros.serving.pool import PoolHealth, SolverPool
from sik_ros.solver import IKResult, PathResult, SelectiveIK

#: ``log(level, message)`` with :mod:`logging` levels.
Log = Callable[[int, str], None]


class Solver(Protocol):
    """What a server solves with: :class:`SelectiveIK`'s two calls, safe from many threads."""

    #: time the solvers took to warm up before serving [s]
    warm_up_seconds: float

    def solve(self, *args: Any, **kwargs: Any) -> IKResult:
        """:meth:`SelectiveIK.solve` with the settings in force."""

    def solve_path(self, *args: Any, **kwargs: Any) -> PathResult:
        """:meth:`SelectiveIK.solve_path` with the settings in force."""

    def configure(self, **settings: Any) -> None:
        """Change some :class:`~sik_ros.solver.SolverConfig` fields for the next requests."""

    def health(self) -> Optional[PoolHealth]:
        """The solver processes' capacity (None without processes)."""

    def processes(self) -> int:
        """How many solver processes it solves in (0: none, in this process's threads)."""

    def close(self) -> None:
        """Stop what the solvers started (idempotent)."""


@dataclass
class _Instance:
    """A solver instance and the settings version it has taken."""

    ik: SelectiveIK
    version: int = 0


class _Settings:
    """The settings in force and their version, changed from any thread."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.values: Dict[str, Any] = {}
        self.version = 0

    def change(self, settings: Dict[str, Any]) -> None:
        """Put ``settings`` in force (a new version) unless they already are."""
        with self._lock:
            merged = dict(self.values, **settings)
            if merged != self.values:
                self.values, self.version = merged, self.version + 1

    def bring(self, instance: _Instance) -> SelectiveIK:
        """``instance``'s solver, configured with the settings in force (in place, once)."""
        version, values = self.version, self.values
        if instance.version != version:
            instance.ik.configure(**values)  # keeps its Pinocchio and coal data
            instance.version = version
        return instance.ik


class LocalSolvers:
    """Clones of one solver in this process, one per executor thread."""

    def __init__(self, ik: SelectiveIK, clones: int):
        """Make and warm up ``clones`` clones of ``ik`` (with ``ik``'s settings).

        The first is warmed up before this returns (``warm_up_seconds``), the others by a
        thread of their own (``warming``), each joining the free ones once warm: a node answers
        from its first clone while the others get ready.
        """
        self._settings = _Settings()
        self._clones: 'queue.LifoQueue[_Instance]' = queue.LifoQueue()
        first = ik.clone()
        self.warm_up_seconds = first.warm_up()
        self._clones.put(_Instance(first))
        rest = [ik.clone() for _ in range(clones - 1)]

        def warm() -> None:
            for clone in rest:
                clone.warm_up()
                self._clones.put(_Instance(clone))

        self.warming = threading.Thread(target=warm, name='sik_warm_up', daemon=True)
        self.warming.start()

    def solve(self, *args: Any, **kwargs: Any) -> IKResult:
        """:meth:`SelectiveIK.solve` on a free clone."""
        with self._borrow() as ik:
            return ik.solve(*args, **kwargs)

    def solve_path(self, *args: Any, **kwargs: Any) -> PathResult:
        """:meth:`SelectiveIK.solve_path` on a free clone."""
        with self._borrow() as ik:
            return ik.solve_path(*args, **kwargs)

    def configure(self, **settings: Any) -> None:
        """Change some config fields; each clone takes them before its next request."""
        self._settings.change(settings)

    def health(self) -> Optional[PoolHealth]:
        """None: no solver processes."""
        return None

    def processes(self) -> int:
        """0: clones in this process's threads."""
        return 0

    def close(self) -> None:
        """Nothing to stop."""

    @contextmanager
    def _borrow(self) -> Iterator[SelectiveIK]:
        instance = self._clones.get()
        try:
            yield self._settings.bring(instance)
        finally:
            self._clones.put(instance)


class PooledSolvers:
    """Solver processes, and the node's own solver while they cannot serve."""

    def __init__(self, ik: SelectiveIK, processes: int, log: Log):
        """Start ``processes`` solver processes with ``ik``'s bundle and settings.

        Raises:
            SikError: a solver process could not start.
        """
        self._settings = _Settings()
        self._own = _Instance(ik)
        self._own_lock = threading.Lock()
        self._log = log
        self.pool = SolverPool(ik.bundle, ik.config, processes, log=log)
        self.warm_up_seconds = ik.warm_up()

    def solve(self, *args: Any, **kwargs: Any) -> IKResult:
        """:meth:`SelectiveIK.solve` in a solver process (or here, see the module)."""
        return self._call(self.pool.solve, SelectiveIK.solve, args, kwargs)

    def solve_path(self, *args: Any, **kwargs: Any) -> PathResult:
        """:meth:`SelectiveIK.solve_path` in a solver process (or here, see the module)."""
        return self._call(self.pool.solve_path, SelectiveIK.solve_path, args, kwargs)

    def _call(self, remote: Callable[..., Any], local: Callable[..., Any], args: tuple,
              kwargs: Dict[str, Any]) -> Any:
        """``remote(*args, **kwargs)`` in a process, else ``local(own solver, ...)`` here."""
        start = time.monotonic()
        try:
            return remote(*args, **kwargs)
        except SolverTimeout:
            raise
        except (SolverUnavailable, SolverCrashed):
            kwargs = self._fall_back(kwargs, start)
        with self._borrow(kwargs.get('timeout')) as ik:
            return local(ik, *args, **kwargs)

    def configure(self, **settings: Any) -> None:
        """Change some config fields in the processes and the node's own solver."""
        self.pool.configure(**settings)
        self._settings.change(settings)

    def health(self) -> Optional[PoolHealth]:
        """The solver processes' capacity."""
        return self.pool.health()

    def processes(self) -> int:
        """The number of solver processes."""
        return self.pool.processes

    def close(self) -> None:
        """Stop the solver processes (idempotent)."""
        self.pool.close()
        self._log(logging.DEBUG, 'solver processes stopped')

    def _fall_back(self, kwargs: Dict[str, Any], start: float) -> Dict[str, Any]:
        """``kwargs`` for the node's own solver: what is left of a timeout counted from ``start``.

        Raises:
            SolverTimeout: nothing is left.
        """
        if kwargs.get('timeout') is None:
            return kwargs
        left = kwargs['timeout'] - (time.monotonic() - start)
        if left <= 0:
            raise SolverTimeout('the solver processes could not serve this request within its '
                                'timeout') from None
        return dict(kwargs, timeout=left)

    @contextmanager
    def _borrow(self, timeout: Optional[float]) -> Iterator[SelectiveIK]:
        """The node's own solver, configured (one request at a time).

        Raises:
            SolverTimeout: it stayed busy for the whole ``timeout``.
        """
        start = time.monotonic()
        if not self._own_lock.acquire(timeout=-1 if timeout is None else timeout):
            raise SolverTimeout('every solver was busy for the request\'s whole timeout '
                                f'({time.monotonic() - start:.2f} s)')
        try:
            yield self._settings.bring(self._own)
        finally:
            self._own_lock.release()


def make_solvers(ik: SelectiveIK, processes: int, clones: int, log: Log) -> Solver:
    """The node's solvers: ``processes`` solver processes, or ``clones`` clones of ``ik``.

    Raises:
        SikError: a solver process could not start.
    """
    if processes > 0:
        return PooledSolvers(ik, processes, log)
    return LocalSolvers(ik, clones)
