"""Solver processes: :meth:`SelectiveIK.solve` in parallel beyond Python's GIL.

The solver is NumPy, Pinocchio and torch code driven from Python, so threads of one process
take turns on the GIL and a second core stays idle. sik_node therefore hands each request to one
of a few solver processes (``multiprocessing`` with the *spawn* start method, so no ROS or DDS
state is inherited), each holding its own :class:`SelectiveIK`; the executor thread that serves
the request waits on a pipe, without the GIL, while it solves.

A worker that dies is replaced in the background; the request it was serving is retried once on
another (:class:`SolverCrashed` if that fails too), and one that does not answer within the
request's deadline is killed and replaced (:class:`SolverTimeout`).
Library errors (:class:`~sik_ros.errors.SikError` subclasses) come back with their own type and
message.
"""

from dataclasses import asdict
import multiprocessing
from multiprocessing.connection import Connection
import queue
import signal
import threading
import time
from typing import Any, Dict, List, Optional

from threadpoolctl import threadpool_limits

from sik_ros import errors
from sik_ros.errors import SikError
from sik_ros.solver import IKResult, SelectiveIK, SolverConfig

#: Seconds a new solver process may take to import its modules and load the bundle.
START_TIMEOUT = 120.0
#: Time a process may take beyond a request's timeout before the watchdog replaces it [s].
WATCHDOG_MARGIN = 0.5


class SolverCrashed(SikError):
    """A solver process died while it served a request (it has been replaced)."""


class SolverTimeout(SikError):
    """No solver process answered within the request's deadline."""


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
    processes on the same cores costs more than it gains (measured: a path's start solve 28
    against 14 ms with a training job on the other core).
    """
    import torch
    torch.set_num_threads(1)
    threadpool_limits(1, user_api='blas')


def _serve(conn: Connection, bundle: str, config: Dict[str, Any]) -> None:
    """Body of a solver process: load the bundle, then answer ``(settings, args, kwargs)``."""
    # the parent owns SIGINT/SIGTERM and closes the pipe to stop us
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    single_threaded()
    try:
        base = SelectiveIK.load(bundle, SolverConfig(**config))
        base.warm_up()
    except Exception as exc:  # reported to the parent, which refuses to start
        conn.send(('error', type(exc).__name__, str(exc)))
        return
    conn.send(('ready', None, None))
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):
            return
        if message is None:
            return
        settings, args, kwargs = message
        try:
            # one instance follows the settings (in place: no memory grows with their churn)
            if any(getattr(base.config, k) != v for k, v in settings.items()):
                base.configure(**settings)
            reply = ('ok', base.solve(*args, **kwargs), None)
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
        except (BrokenPipeError, OSError):
            pass
        self.process.join(timeout)
        if self.process.is_alive():
            self.process.kill()
            self.process.join(timeout)
        self.conn.close()


class SolverPool:
    """``processes`` solver processes, each serving one request at a time, for many threads."""

    def __init__(self, bundle: str, config: SolverConfig, processes: int):
        """Start the processes and wait until every one has loaded ``bundle``.

        Raises:
            SikError: a process could not load the bundle or did not start in time.
        """
        if processes < 1:
            raise errors.InvalidArgument(f'processes must be at least 1; got {processes}')
        self._ctx = multiprocessing.get_context('spawn')
        self._bundle, self._config = str(bundle), asdict(config)
        self._idle: 'queue.Queue[_Worker]' = queue.Queue()
        self._all: List[_Worker] = []
        self._lock = threading.Lock()
        self._closed = False
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

    def solve(self, settings: Dict[str, Any], *args, **kwargs) -> IKResult:
        """:meth:`SelectiveIK.solve` with the config fields ``settings`` changed, in a process.

        The request's ``timeout`` bounds the whole call (plus :data:`WATCHDOG_MARGIN`): waiting
        for a free process, the solve, and a retry. A process found dead while idle is
        replaced in the background and another one serves; a process that dies while solving
        is replaced and the request retried once on another within its deadline; one that
        does not answer in time is killed and replaced (a watchdog).

        Raises:
            SikError: what the solver raised (same type and message), SolverCrashed, or
                SolverTimeout.
        """
        timeout = kwargs.get('timeout')
        deadline = None if timeout is None else time.monotonic() + timeout + WATCHDOG_MARGIN
        for attempt in range(2):
            worker = self._take(deadline)
            try:
                worker.conn.send((settings, args, kwargs))
                left = None if deadline is None else max(0.0, deadline - time.monotonic())
                if not worker.conn.poll(left):
                    self._replace_later(worker)
                    worker = None
                    raise SolverTimeout('the solver process did not answer within the '
                                        'request\'s deadline; it has been replaced')
                kind, payload, message = worker.conn.recv()
            except (EOFError, OSError) as exc:
                self._replace_later(worker)
                worker = None
                if attempt == 0 and (deadline is None or time.monotonic() < deadline):
                    continue  # once more, on another process
                raise SolverCrashed('the solver process serving this request died; it has '
                                    'been replaced') from exc
            finally:
                if worker is not None:
                    self._idle.put(worker)
            if kind == 'error':
                raise rebuild_error(payload, message)
            return payload
        raise SolverCrashed('no solver process could serve this request')  # pragma: no cover

    def _take(self, deadline: Optional[float]) -> '_Worker':
        """An idle, living process; dead ones met on the way are replaced in the background.

        Raises:
            SolverTimeout: none is free before ``deadline``.
        """
        while True:
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            try:
                worker = self._idle.get(timeout=left)
            except queue.Empty:
                raise SolverTimeout('no solver process was free within the request\'s '
                                    'deadline') from None
            if worker.process.is_alive():
                return worker
            self._replace_later(worker)

    def _replace_later(self, dead: '_Worker') -> None:
        """Start a process in place of ``dead``; it joins the idle ones once it has loaded."""
        def start() -> None:
            fresh = self._replace(dead)
            if fresh is not None:
                self._idle.put(fresh)
        threading.Thread(target=start, name='sik_solver_restart', daemon=True).start()

    def _replace(self, dead: _Worker) -> Optional[_Worker]:
        """A new process in place of a dead one (None if the pool is closing or it fails)."""
        with self._lock:
            if self._closed or dead not in self._all:
                return None
            index = self._all.index(dead)
            dead.stop(timeout=0.5)
            fresh = _Worker(self._ctx, self._bundle, self._config, index)
            self._all[index] = fresh
        try:
            fresh.wait_ready(START_TIMEOUT)
        except SikError:
            return None
        with self._lock:
            if self._closed:
                fresh.stop(timeout=1.0)
                return None
        return fresh

    def close(self) -> None:
        """Stop every process (idempotent)."""
        with self._lock:
            self._closed = True
            workers, self._all = list(self._all), []
        for w in workers:
            w.stop()
