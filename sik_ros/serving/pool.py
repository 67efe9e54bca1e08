"""Solver processes: :class:`SelectiveIK` solves and paths in parallel beyond Python's GIL.

The solver is NumPy, Pinocchio and torch code driven from Python, so threads of one process
take turns on the GIL and a second core stays idle. sik_node therefore hands each request to one
of a few solver processes (``multiprocessing`` with the *spawn* start method, so no ROS or DDS
state is inherited), each holding its own :class:`SelectiveIK`; the executor thread that serves
the request waits on a pipe, without the GIL, while it solves.

The pool heals: a process that dies, or is killed by the watchdog (no answer within a request's
deadline), is replaced in the background, and a replacement that fails to start is retried with
a growing back-off until one starts or the pool closes, each step logged. While a process is
missing, a request that finds none idle gets :class:`~sik_ros.errors.SolverUnavailable` at once
(the node then solves it itself) instead of waiting for a process that may never come; the
request a dying process was serving is retried once on another (:class:`SolverCrashed` if none
can take it). :meth:`SolverPool.health` tells the capacity. Library errors
(:class:`~sik_ros.errors.SikError` subclasses) come back with their own type and message.
"""

from dataclasses import asdict, dataclass
import logging
import multiprocessing
from multiprocessing.connection import Connection
import os
import queue
import signal
import sys
import threading
import time
from typing import Any, Callable, Dict, List, Optional

from threadpoolctl import threadpool_limits

from sik_ros import errors
from sik_ros.deadline import Deadline
from sik_ros.errors import SikError, SolverCrashed, SolverTimeout, SolverUnavailable
from sik_ros.solver import IKResult, PathResult, SelectiveIK, SolverConfig

__all__ = ['PoolHealth', 'SolverCrashed', 'SolverPool', 'SolverTimeout', 'SolverUnavailable',
           'single_threaded']

#: Seconds a new solver process may take to import its modules and load the bundle.
START_TIMEOUT = 120.0
#: Time a process may take beyond a request's timeout before the watchdog replaces it [s].
WATCHDOG_MARGIN = 0.5
#: Waits before the next try to start a replacement that failed [s]: doubling, capped.
RESTART_BACKOFF, RESTART_BACKOFF_MAX = 0.25, 8.0

#: ``log(level, message)``: where the pool reports lost and restored capacity.
Log = Callable[[int, str], None]


def _default_log(level: int, message: str) -> None:
    logging.getLogger('sik_ros.serving.pool').log(level, message)


@dataclass(frozen=True)
class PoolHealth:
    """The solver processes' capacity.

    Attributes:
        processes: processes the pool is meant to have.
        ready: processes started and serving (idle or busy).
        restarts: replacements started since the pool began.
        failed_starts: replacements that failed to start (each retried after a back-off).
        idle: ready processes waiting for a request.
    """

    processes: int
    ready: int
    restarts: int
    failed_starts: int
    idle: int = 0


def rebuild_error(name: str, message: str) -> SikError:
    """The library error named ``name`` (a SikError subclass), carrying ``message``."""
    cls = getattr(errors, name, None)
    if not (isinstance(cls, type) and issubclass(cls, SikError)):
        cls = SikError
    exc = cls.__new__(cls)
    Exception.__init__(exc, message)
    return exc


def single_threaded() -> None:
    """One thread for torch and for NumPy's BLAS in this process (a solver's products are small).

    A solve multiplies matrices of a few rows (the networks' layers, batched Jacobians);
    OpenBLAS splits even those over every core, which with the node's other solver threads or
    processes on the same cores costs more than it gains (docs/design.md, "Measured
    choices").
    """
    torch = sys.modules.get('torch')
    if torch is not None:
        torch.set_num_threads(1)
    else:  # read when torch is imported (a bundle without NumPy twins): not imported for this
        os.environ['OMP_NUM_THREADS'] = '1'
    threadpool_limits(1, user_api='blas')


def _serve(conn: Connection, bundle: str, config: Dict[str, Any]) -> None:
    """Body of a solver process: load the bundle, then answer ``(method, settings, ...)``.

    Each message is ``(method, settings, args, kwargs)``: ``settings`` is None, or, when they
    changed since this process's last message, every config field the pool has changed since
    it started; None or a closed pipe ends it.
    """
    # the parent owns SIGINT/SIGTERM and closes the pipe to stop us
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    single_threaded()
    try:
        base = SelectiveIK.load(bundle, SolverConfig(**config))
        base.warm_up()
    except Exception as exc:  # reported to the parent, which refuses to start
        conn.send(('error', type(exc).__name__, str(exc)))
        return
    methods = {'solve': base.solve, 'solve_path': base.solve_path}
    conn.send(('ready', None, None))
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):
            return
        if message is None:
            return
        method, settings, args, kwargs = message
        try:
            if settings:
                base.configure(**settings)  # in place: no memory grows with their churn
            call = methods.get(method)
            if call is None:
                raise errors.InvalidArgument(f'solver processes serve {sorted(methods)}; got '
                                             f'{method!r}')
            reply = ('ok', call(*args, **kwargs), None)
        except SikError as exc:
            reply = ('error', type(exc).__name__, str(exc))
        except Exception as exc:  # any other failure is the request's, not the process's
            reply = ('error', 'SikError', f'solver failure: {type(exc).__name__}: {exc}')
        try:
            conn.send(reply)
        except (BrokenPipeError, OSError):
            return


class _Worker:
    """One solver process and the parent's end of its pipe."""

    def __init__(self, ctx, bundle: str, config: Dict[str, Any], index: int):
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=_serve, args=(child, bundle, config),
                                   name=f'sik_solver_{index}', daemon=True)
        self.process.start()
        child.close()
        #: the pool's settings version this process has (it starts with the pool's config)
        self.version = 0

    def wait_ready(self, timeout: float) -> None:
        """Block until the process has loaded the bundle (raises SikError if it cannot)."""
        if not self.conn.poll(timeout):
            self.stop()
            raise SikError(f'solver process did not start within {timeout:.0f} s')
        try:
            kind, name, message = self.conn.recv()
        except (EOFError, OSError) as exc:
            raise SikError(f'solver process exited while starting (exit code '
                           f'{self.process.exitcode})') from exc
        if kind != 'ready':
            self.stop()
            raise rebuild_error(name, message)

    def stop(self, timeout: float = 5.0) -> None:
        """Ask the process to exit, then make sure it has."""
        try:
            self.conn.send(None)
        except (BrokenPipeError, OSError, ValueError):
            pass
        self.process.join(timeout)
        if self.process.is_alive():
            self.process.kill()
            self.process.join(timeout)
        self.conn.close()


class SolverPool:
    """``processes`` solver processes, each serving one request at a time, for many threads."""

    def __init__(self, bundle: str, config: SolverConfig, processes: int,
                 log: Optional[Log] = None):
        """Start the processes and wait until every one has loaded ``bundle``.

        Args:
            bundle: the bundle directory or name each process loads.
            config: the solver settings each process starts with.
            processes: how many processes.
            log: ``log(level, message)`` (``logging`` levels) for lost and restored capacity;
                default: the ``sik_ros.serving.pool`` logger.

        Raises:
            SikError: a process could not load the bundle or did not start in time.
        """
        if processes < 1:
            raise errors.InvalidArgument(f'processes must be at least 1; got {processes}')
        self._ctx = multiprocessing.get_context('spawn')
        self._bundle, self._config = str(bundle), asdict(config)
        self._log = log or _default_log
        #: how many processes it keeps (restarted ones included)
        self.processes = processes
        self._idle: 'queue.Queue[_Worker]' = queue.Queue()
        self._all: List[_Worker] = []
        self._lock = threading.Lock()
        self._closed = False
        self._missing = 0
        self._restarts = self._failed_starts = 0
        #: config fields changed since the start, and how many times they changed
        self._settings: Dict[str, Any] = {}
        self._version = 0
        try:
            for i in range(processes):
                self._all.append(_Worker(self._ctx, self._bundle, self._config, i))
            for w in self._all:
                w.wait_ready(START_TIMEOUT)
        except BaseException:
            self.close()
            raise
        for w in self._all:
            self._idle.put(w)

    @property
    def pids(self) -> List[int]:
        """Process ids of the solver processes."""
        with self._lock:
            return [w.process.pid for w in self._all]

    def health(self) -> PoolHealth:
        """How many processes serve, of how many, and the restarts so far."""
        with self._lock:
            return PoolHealth(len(self._all), len(self._all) - self._missing, self._restarts,
                              self._failed_starts, self._idle.qsize())

    @property
    def busy_pids(self) -> List[int]:
        """Process ids of the processes serving a request now."""
        with self._lock:
            idle = {id(w) for w in list(self._idle.queue)}
            return [w.process.pid for w in self._all if id(w) not in idle]

    def configure(self, **settings: Any) -> None:
        """Change some config fields: each process takes them with its next request.

        Processes started later (replacements) start with them.
        """
        with self._lock:
            merged = dict(self._settings, **settings)
            if merged != self._settings:
                self._settings, self._version = merged, self._version + 1
                self._config = dict(self._config, **settings)

    def solve(self, *args, **kwargs) -> IKResult:
        """:meth:`SelectiveIK.solve` in a process, with the settings in force (:meth:`call`)."""
        return self.call('solve', *args, **kwargs)

    def solve_path(self, *args, **kwargs) -> PathResult:
        """:meth:`SelectiveIK.solve_path` in a process, with the settings in force."""
        return self.call('solve_path', *args, **kwargs)

    def call(self, method: str, *args, **kwargs):
        """``SelectiveIK.<method>(*args, **kwargs)`` in a solver process (solve, solve_path).

        The request's ``timeout`` bounds the whole call (plus :data:`WATCHDOG_MARGIN`): waiting
        for a free process, the solve, and a retry. A process found dead while idle is
        replaced in the background and another one serves; a process that dies while solving
        is replaced and the request retried once on another within its deadline; one that
        does not answer in time is killed and replaced (a watchdog).

        Raises:
            SikError: what the solver raised (same type and message); SolverUnavailable when
                a process is missing and none is idle; SolverCrashed; SolverTimeout.
        """
        timeout = kwargs.get('timeout')
        deadline = Deadline.after(None if timeout is None else timeout + WATCHDOG_MARGIN)
        for attempt in range(2):
            worker = self._take(deadline)
            try:
                settings, version = None, self._version
                if worker.version != version:
                    settings, worker.version = self._settings, version
                worker.conn.send((method, settings, args, kwargs))
                left = max(0.0, deadline.remaining()) if deadline.bounded else None
                if not worker.conn.poll(left):
                    self._replace_later(worker, 'it did not answer within a request\'s deadline')
                    worker = None
                    raise SolverTimeout('the solver process did not answer within the '
                                        'request\'s deadline; it is being replaced')
                kind, payload, message = worker.conn.recv()
            except (EOFError, OSError) as exc:
                self._replace_later(worker, 'it died while serving a request')
                worker = None
                if attempt == 0 and not deadline.expired():
                    continue  # once more, on another process
                raise SolverCrashed('the solver process serving this request died; it is '
                                    'being replaced') from exc
            finally:
                if worker is not None:
                    self._idle.put(worker)
            if kind == 'error':
                raise rebuild_error(payload, message)
            return payload
        raise SolverCrashed('no solver process could serve this request')  # pragma: no cover

    def _take(self, deadline: Deadline) -> '_Worker':
        """An idle, living process; dead ones met on the way are replaced in the background.

        Raises:
            SolverUnavailable: none is idle while some are missing (being restarted).
            SolverTimeout: none is free before ``deadline``.
        """
        while True:
            try:
                worker = self._idle.get_nowait()
            except queue.Empty:
                if self._missing:
                    raise SolverUnavailable(
                        f'{self._missing} of {len(self._all)} solver processes are being '
                        f'restarted and the others are busy') from None
                left = max(0.0, deadline.remaining()) if deadline.bounded else None
                try:
                    worker = self._idle.get(timeout=left)
                except queue.Empty:
                    raise SolverTimeout('no solver process was free within the request\'s '
                                        'deadline') from None
            if worker.process.is_alive():
                return worker
            self._replace_later(worker, f'it exited (code {worker.process.exitcode})')

    def _replace_later(self, dead: '_Worker', why: str) -> None:
        """Replace ``dead`` in the background, retrying failed starts with a back-off."""
        with self._lock:
            if self._closed or dead not in self._all:
                return
            self._missing += 1
            index = self._all.index(dead)
            ready = len(self._all) - self._missing
            total = len(self._all)
        self._log(logging.WARNING, f'solver process {index} lost: {why}; {ready} of {total} '
                  f'serving while it restarts (requests beyond them are solved in the node)')
        threading.Thread(target=self._restart, args=(dead, index), name='sik_solver_restart',
                         daemon=True).start()

    def _restart(self, dead: '_Worker', index: int) -> None:
        """Start processes in place of ``dead`` until one loads the bundle or the pool closes."""
        dead.stop(timeout=0.5)
        wait = RESTART_BACKOFF
        tries = 0
        while True:
            fresh = None
            try:
                with self._lock:
                    if self._closed:
                        return
                    fresh = _Worker(self._ctx, self._bundle, self._config, index)
                    fresh.version = self._version  # started with the settings in force
                    self._all[index] = fresh
                    self._restarts += 1
                tries += 1
                fresh.wait_ready(START_TIMEOUT)
            except Exception as exc:  # whatever stopped this start, the next one may work
                with self._lock:
                    self._failed_starts += 1
                self._log(logging.WARNING, f'solver process {index} failed to start (try '
                          f'{tries}: {exc}); next try in {wait:g} s')
                if fresh is not None:
                    fresh.stop(timeout=0.5)
                time.sleep(wait)
                wait = min(2 * wait, RESTART_BACKOFF_MAX)
                continue
            with self._lock:
                if self._closed:
                    fresh.stop(timeout=1.0)
                    return
                self._missing -= 1
                ready, total = len(self._all) - self._missing, len(self._all)
            self._idle.put(fresh)
            self._log(logging.INFO, f'solver process {index} restarted (try {tries}): {ready} '
                      f'of {total} serving')
            return

    def close(self) -> None:
        """Stop every process (idempotent)."""
        with self._lock:
            self._closed = True
            workers, self._all = list(self._all), []
        for w in workers:
            w.stop()
