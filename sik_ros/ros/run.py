"""Running sik_node: start-up, the spin loop, and a shutdown that drains within its grace period.

The node owns SIGINT and SIGTERM (systemd, docker stop, kill): both raise KeyboardInterrupt in
the main thread, which spins with a short timeout so that it gets back to Python, and so to the
handler, at least every ``SPIN_PERIOD`` seconds. On either, new requests are answered TIMEOUT,
in-flight ones get ``shutdown_grace`` seconds to finish, and the process exits 0 within that
plus about a second whatever is still running.
"""

import os
import signal
import sys
import time
from typing import List, Optional

import rclpy
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.signals import SignalHandlerOptions

from sik_ros.errors import SikError
from sik_ros.ros.lifecycle import make_node
from sik_ros.ros.node import NODE_NAME, SPIN_PERIOD


def _stop(signum, frame) -> None:
    """SIGINT and SIGTERM: leave the spin loop (raised in the main thread)."""
    raise KeyboardInterrupt


def main(args: Optional[List[str]] = None) -> int:
    """Run sik_node until SIGINT/SIGTERM; exit code 1 (one FATAL log line) if it cannot start."""
    # The node owns SIGINT and SIGTERM (systemd, docker stop, kill): both raise
    # KeyboardInterrupt in the main thread, which spins with a short timeout so that it gets
    # back to Python, and so to the handler, at least every SPIN_PERIOD seconds.
    signal.signal(signal.SIGINT, _stop)
    signal.signal(signal.SIGTERM, _stop)
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
        node = make_node()
    except KeyboardInterrupt:  # stopped during start-up: not a failure
        rclpy.try_shutdown()
        return 0
    except Exception as exc:  # one clear line instead of a traceback, whatever failed
        reason = ' '.join(str(exc).split())
        if not isinstance(exc, SikError):
            reason = f'{type(exc).__name__}: {reason}'
        rclpy.logging.get_logger(NODE_NAME).fatal(f'cannot start: {reason}')
        rclpy.try_shutdown()
        return 1
    executor = MultiThreadedExecutor(num_threads=node.workers)
    executor.add_node(node)
    try:
        while rclpy.ok() and not getattr(node, 'finished', False):  # a managed node's shutdown
            try:
                executor.spin_once(timeout_sec=SPIN_PERIOD)
            except (KeyboardInterrupt, ExternalShutdownException):
                raise
            except Exception as exc:  # a callback's failure must not stop the node
                _log_error('a callback failed (the node goes on)', exc)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second signal must not break clean-up
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        # in-flight requests get the grace period; requests arriving now get TIMEOUT
        node.closing = True
        deadline = time.monotonic() + node.shutdown_grace
        try:
            while node.in_flight and time.monotonic() < deadline:
                executor.spin_once(timeout_sec=0.02)  # lets finished requests send answers
        except Exception as exc:  # the interrupted executor could not go on: exit anyway
            _log_error('during shutdown, draining the requests in flight failed', exc)
        if node.in_flight:  # still solving past the grace period: do not wait for it
            rclpy.logging.get_logger(NODE_NAME).warning(
                f'exiting with {node.in_flight} request(s) still in flight after the '
                f'{node.shutdown_grace:g} s grace period')
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(0)
        time.sleep(0.1)  # the last answers leave their threads
        for what, step in (('stopping the executor', lambda: executor.shutdown(timeout_sec=0)),
                           ('closing the node', node.destroy_node),
                           ('shutting ROS down', rclpy.try_shutdown)):
            try:
                step()
            except Exception as exc:  # one line, and the other steps still run
                _log_error(f'during shutdown, {what} failed', exc)
    return 0


def _log_error(what: str, exc: Exception) -> None:
    """One ERROR line for something that failed while the node goes on (or shuts down)."""
    reason = ' '.join(str(exc).split())
    rclpy.logging.get_logger(NODE_NAME).error(f'{what}: {type(exc).__name__}: {reason}')


if __name__ == '__main__':
    raise SystemExit(main())
