"""The node's executor: several threads, and work taken only when a thread is free.

rclpy's :class:`~rclpy.executors.MultiThreadedExecutor` (7.1) hands every ready callback to a
thread pool at once. A callback's message or request is taken inside its task, on the pool's
thread, and the executor yields every task that has not started yet again on each of its
turns: while every thread is busy, each turn submits the waiting tasks once more and scans a
list of futures that grows with them, so the spinning thread holds the GIL in a loop that gets
longer the more work waits, and the threads that solve get less of it (docs/design.md, "The
executor"). :class:`SlottedExecutor` asks the wait set for work only when one of its threads
is free: a turn waits for a free thread (not holding the GIL), takes one ready callback and
hands it to that thread, so nothing is submitted twice for long and nothing piles up in the
executor; what waits, waits in DDS's queues under the QoS of its subscription or service.

:func:`after_answer` lets a callback leave work for after its answer: a service's response is
sent when its callback returns, and the work runs then, on the same thread.
"""

from collections import deque
from concurrent.futures import ThreadPoolExecutor
import threading
from typing import Callable, Deque, List, Optional

from rclpy.executors import (ConditionReachedException, Executor, ExternalShutdownException,
                             ShutdownException, TimeoutException)
from rclpy.task import Future


_local = threading.local()


def after_answer(work: Callable[[], None]) -> None:
    """Run ``work()`` once the callback running on this thread has finished (its answer sent).

    On a thread of :class:`SlottedExecutor` the work waits until the callback's response is
    sent; elsewhere (another executor, a thread of the node's own) it runs at once. It must not
    raise.
    """
    pending: Optional[List[Callable[[], None]]] = getattr(_local, 'pending', None)
    if pending is None:
        work()
    else:
        pending.append(work)


class SlottedExecutor(Executor):
    """An executor of ``num_threads`` threads that takes a callback only for a free thread."""

    def __init__(self, num_threads: int, *, context=None) -> None:
        """Create the thread pool.

        Args:
            num_threads: threads running callbacks (at least 1).
            context: the rclpy context (default: the global one).
        """
        super().__init__(context=context)
        if num_threads < 1:
            raise ValueError(f'num_threads must be at least 1; got {num_threads}')
        self._pool = ThreadPoolExecutor(max_workers=num_threads,
                                        thread_name_prefix='sik_executor')
        self._slots = threading.Semaphore(num_threads)
        self._errors: Deque[BaseException] = deque()

    def spin_once(self, timeout_sec: Optional[float] = None) -> None:
        """Wait for a free thread and a ready callback, and start it on that thread.

        Raises:
            Exception: what a callback that finished since the last turn raised (as
                ``MultiThreadedExecutor`` does), once.
        """
        self._spin_once(timeout_sec, lambda: False)

    def spin_once_until_future_complete(self, future: Future,
                                        timeout_sec: Optional[float] = None) -> None:
        """:meth:`spin_once`, returning early once ``future`` is done."""
        future.add_done_callback(lambda _: self.wake())
        self._spin_once(timeout_sec, future.done)

    def _spin_once(self, timeout_sec: Optional[float], condition: Callable[[], bool]) -> None:
        self._raise_pending()
        blocking = timeout_sec is None or timeout_sec < 0
        if not self._slots.acquire(timeout=None if blocking else timeout_sec):
            return
        try:
            handler, _, _ = self.wait_for_ready_callbacks(timeout_sec, None, condition)
        except (TimeoutException, ShutdownException, ExternalShutdownException,
                ConditionReachedException):
            self._slots.release()
            return
        except BaseException:
            self._slots.release()
            raise
        self._pool.submit(self._run, handler)

    def _run(self, handler) -> None:
        _local.pending = pending = []
        try:
            handler()
            if handler.done() and handler.exception() is not None:
                self._errors.append(handler.exception())
            for work in pending:  # the callback's answer has been sent
                work()
        finally:
            _local.pending = None
            self._slots.release()

    def _raise_pending(self) -> None:
        if self._errors:
            raise self._errors.popleft()

    def shutdown(self, timeout_sec: Optional[float] = None) -> bool:
        """Stop the executor, then its threads (without waiting for running callbacks)."""
        done = super().shutdown(timeout_sec)
        self._pool.shutdown(wait=False)
        return done
