"""One guard around every request the node answers: refusals, counting, errors into codes.

Both services and the goal topic answer through :meth:`RequestGuard.answer`. It refuses requests
while the node closes or while a refusal (a robot_description that does not fit the bundle, an
inactive managed node) holds; it counts the requests in flight; and it turns whatever the
handler raises into an error code and a message: a library error
(:class:`~sik_ros.errors.SikError`) into its code, anything else into ``INTERNAL_ERROR``, logged
with its traceback. Nothing raised by a handler reaches the executor, and a response that could
not be filled is replaced by a fresh one carrying the code.
"""

from contextlib import contextmanager
import logging
import threading
import time
import traceback
from typing import Callable, Iterator, List, Optional, Tuple, TypeVar

from sik_interfaces.srv import SolveIK
from sik_ros.errors import SikError
from sik_ros.ros import conversions as conv

R = SolveIK.Response
#: A refusal check: ``(code, message)`` while requests must be refused, else None.
Refusal = Callable[[], Optional[Tuple[int, str]]]
#: ``listener(where, code, seconds)``: called after every answer (statistics, diagnostics).
Listener = Callable[[str, int, float], None]
Response = TypeVar('Response')


class RequestGuard:
    """Answers requests through handlers that may fail; safe from every executor thread."""

    def __init__(self, logger):
        """Guard requests, logging to ``logger`` (an rclpy logger)."""
        self._logger = logger
        #: set on SIGINT/SIGTERM: new requests are answered TIMEOUT
        self.closing = False
        self.refusals: List[Refusal] = []
        self.listeners: List[Listener] = []
        self._in_flight = 0
        self._lock = threading.Lock()

    @property
    def in_flight(self) -> int:
        """Requests being answered now."""
        return self._in_flight

    def refusal(self) -> Optional[Tuple[int, str]]:
        """The code and message every request gets now, or None when requests are served."""
        if self.closing:
            return R.TIMEOUT, 'sik_node is shutting down'
        for check in self.refusals:
            refused = check()
            if refused is not None:
                return refused
        return None

    def answer(self, where: str, response: Response,
               fill: Callable[[Response], Tuple[int, str]]) -> Response:
        """The answer to one request: ``fill(response)`` sets its payload, returns the code.

        Args:
            where: the request's kind, for logs (``solve_ik``, ``solve_path``, ``goal``).
            response: the empty response message.
            fill: sets the response's payload fields and returns ``(error_code, message)``;
                may raise.

        Returns:
            The response with its ``error_code`` and ``message`` set (a fresh one if ``fill``
            failed half-way).
        """
        t0 = time.perf_counter()
        refused = self.refusal()
        if refused is not None:
            code, message = refused
        else:
            with self._counted():
                try:
                    code, message = fill(response)
                except Exception as exc:  # the node answers every request, whatever fails
                    response = type(response)()
                    code, message = self._code_for(where, exc)
        try:
            response.error_code, response.message = int(code), str(message)
        except Exception as exc:  # a message that cannot be set: a bug, answered as one
            response = type(response)()
            response.error_code, response.message = self._code_for(where, exc)
        if code not in (R.SUCCESS,):
            self._logger.debug(f'{where}: {conv.ERROR_NAMES.get(code, code)}: {message}')
        seconds = time.perf_counter() - t0
        for listener in self.listeners:
            try:
                listener(where, int(response.error_code), seconds)
            except Exception as exc:  # statistics must not cost an answer
                self._logger.error(f'{where}: request listener failed: {exc!r}',
                                   throttle_duration_sec=10.0)
        return response

    def _code_for(self, where: str, exc: Exception) -> Tuple[int, str]:
        """The code and message of an exception raised while answering."""
        if isinstance(exc, SikError):
            code = conv.error_code_for(exc)
            if code == R.INTERNAL_ERROR or code == R.TIMEOUT:
                self._logger.warning(f'{where}: {exc}')
            return code, str(exc)
        self._logger.error(f'{where}: unexpected {type(exc).__name__}: {exc}\n'
                           f'{traceback.format_exc()}')
        return R.INTERNAL_ERROR, f'internal error: {type(exc).__name__}: {exc}'

    @contextmanager
    def _counted(self) -> Iterator[None]:
        """Count a request as in flight while it is answered."""
        with self._lock:
            self._in_flight += 1
        try:
            yield
        finally:
            with self._lock:
                self._in_flight -= 1


def log_at(logger, level: int, message: str) -> None:
    """Log ``message`` on an rclpy logger at a :mod:`logging` level.

    One call site per severity: rclpy refuses a call site whose severity changes.
    """
    if level >= logging.ERROR:
        logger.error(message)
    elif level >= logging.WARNING:
        logger.warning(message)
    elif level >= logging.INFO:
        logger.info(message)
    else:
        logger.debug(message)
