"""Command-line tools of sik_ros (thin wrappers over the library)."""

import argparse
import signal
import sys
import threading
from typing import Callable, List, Optional

from sik_ros.errors import SikError


class Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (``prog: error: ...``) and exit 2."""

    def error(self, message: str):
        """Print the one line and exit 2 (``--help`` still prints the whole usage)."""
        self.exit(2, f'{self.prog}: error: {message} (see --help)\n')


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread so that partial artifacts are removed on the way out.

    A :class:`KeyboardInterrupt`, so that what stops cleanly on Ctrl-C (a training run saving
    its checkpoint) does the same on SIGTERM.
    """


def _stop(signum, frame) -> None:
    """SIGINT or SIGTERM: raise once; a second signal during the clean-up is ignored."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def run_cli(prog: str, body: Callable[[], int],
            on_stop: str = 'partial output removed') -> int:
    """Run a CLI body: one line and exit 2 for a :class:`SikError`; clean stops on signals.

    SIGINT and SIGTERM raise in the body, whose artifacts are written under temporary names
    (:mod:`sik_ros.artifacts`) that are removed as the exception passes; the command then says
    so in one line (``on_stop``: what was kept or removed) and exits 130 (SIGINT) or 143
    (SIGTERM).
    """
    main_thread = threading.current_thread() is threading.main_thread()
    if main_thread:
        previous = {s: signal.signal(s, _stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        return body()
    except SikError as exc:
        print(f'{prog}: error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        what, code = ('terminated (SIGTERM)', 143) if isinstance(exc, Terminated) else \
            ('interrupted (SIGINT)', 130)
        print(f'{prog}: {what}; {on_stop}', file=sys.stderr)
        return code
    finally:
        if main_thread:
            for s, handler in previous.items():
                signal.signal(s, handler)


def argv_or_default(argv: Optional[List[str]]) -> List[str]:
    """The arguments to parse: ``argv`` or the process's."""
    return sys.argv[1:] if argv is None else list(argv)
