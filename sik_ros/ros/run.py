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

from sik_ros.errors import SikError

#: The node's name in its log lines (as ``sik_ros.ros.node.NODE_NAME``, which loads the solver).
LOGGER = 'sik_node'
#: Most seconds the shutdown waits for the callbacks still running (none of them a request)
#: before the node is destroyed.
STOP_WAIT = 1.0


def _stop(signum, frame) -> None:
    """SIGINT and SIGTERM: leave the spin loop (raised in the main thread)."""
    raise KeyboardInterrupt


def user_args(argv: List[str]) -> List[str]:
    """The arguments outside ``--ros-args ... [--]`` blocks (ROS's own are left to rclpy)."""
    out, in_ros = [], False
    for arg in argv:
        if arg == '--ros-args':
            in_ros = True
        elif arg == '--' and in_ros:
            in_ros = False
        elif not in_ros:
            out.append(arg)
    return out


def usage() -> str:
    """``sik_node --help``: how to start it, and every parameter with its default."""
    from sik_ros.ros.params import SPECS  # only here: the node's start needs no help text
    lines = ['usage: sik_node [--ros-args [-p NAME:=VALUE ...] [--params-file FILE] ...]', '',
             'Multi-solution IK services (~/solve_ik, ~/solve_path), the ~/goal topic and '
             '/diagnostics;', 'docs/interfaces.md has every message. Parameters (default):', '']
    for spec in SPECS:
        lines.append(f'  {spec.name} ({spec.type.__name__}, {spec.default!r})')
        lines.append(f'      {" ".join(spec.description.split())}')
    return '\n'.join(lines)


def main(args: Optional[List[str]] = None) -> int:
    """Run sik_node until SIGINT/SIGTERM; exit code 1 (one FATAL log line) if it cannot start.

    ``--help`` prints the usage and the parameters; any other argument outside ``--ros-args``
    is refused (one line, exit code 2).
    """
    mine = user_args(sys.argv[1:] if args is None else list(args))
    if any(a in ('-h', '--help') for a in mine):
        print(usage())
        return 0
    if mine:
        print(f'sik_node: error: unknown argument {mine[0]!r} (parameters go after --ros-args: '
              f'sik_node --ros-args -p NAME:=VALUE; sik_node --help lists them)', file=sys.stderr)
        return 2
    return _serve(args)


def _serve(args: Optional[List[str]]) -> int:
    """Start the node, spin until a signal, drain the requests in flight and shut down."""
    # imported here: ``--help`` and a refused argument answer without loading the solver
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.signals import SignalHandlerOptions

    from sik_ros.ros.executor import SlottedExecutor
    from sik_ros.ros.lifecycle import make_node
    from sik_ros.ros.node import SPIN_PERIOD
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
        rclpy.logging.get_logger(LOGGER).fatal(f'cannot start: {reason}')
        rclpy.try_shutdown()
        return 1
    # a signal may come as soon as the services are up (before the spin loop): from here on
    # it leads to the same drain and clean shutdown
    executor = None
    try:
        executor = SlottedExecutor(node.workers)
        executor.add_node(node)
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
        _drain_and_stop(node, executor)
    return 0


def _drain_and_stop(node, executor) -> None:
    """Give in-flight requests the grace period, then stop the executor, the node and ROS.

    ``executor`` None: the signal came before the executor was made (nothing in flight).
    """
    import rclpy
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second signal must not break clean-up
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    # in-flight requests get the grace period; requests arriving now get TIMEOUT
    node.closing = True
    deadline = time.monotonic() + node.shutdown_grace
    try:
        while executor is not None and node.in_flight and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.02)  # lets finished requests send answers
    except Exception as exc:  # the interrupted executor could not go on: exit anyway
        _log_error('during shutdown, draining the requests in flight failed', exc)
    if node.in_flight:  # still solving past the grace period: do not wait for it
        rclpy.logging.get_logger(LOGGER).warning(
            f'exiting with {node.in_flight} request(s) still in flight after the '
            f'{node.shutdown_grace:g} s grace period')
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(0)
    time.sleep(0.1)  # the last answers leave their threads
    # nothing in flight: the callbacks still running (a timer's, a refusal) are short, and
    # the node is destroyed only after them (at most STOP_WAIT seconds)
    for what, step in (('stopping the executor',
                        lambda: executor is None or executor.shutdown(timeout_sec=STOP_WAIT)),
                       ('closing the node', node.destroy_node),
                       ('shutting ROS down', rclpy.try_shutdown)):
        try:
            step()
        except Exception as exc:  # one line, and the other steps still run
            _log_error(f'during shutdown, {what} failed', exc)


def _log_error(what: str, exc: Exception) -> None:
    """One ERROR line for something that failed while the node goes on (or shuts down)."""
    import rclpy
    reason = ' '.join(str(exc).split())
    rclpy.logging.get_logger(LOGGER).error(f'{what}: {type(exc).__name__}: {reason}')


if __name__ == '__main__':
    raise SystemExit(main())
