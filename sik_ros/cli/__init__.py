"""Command-line tools of sik_ros (thin wrappers over the library)."""

import argparse
import sys
from typing import Callable, List, Optional

from sik_ros.errors import SikError


class Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (``prog: error: ...``) and exit 2."""

    def error(self, message: str):
        """Print the one line and exit 2 (``--help`` still prints the whole usage)."""
        self.exit(2, f'{self.prog}: error: {message} (see --help)\n')


def run_cli(prog: str, body: Callable[[], int]) -> int:
    """Run a CLI body, turning a :class:`SikError` into a one-line message and exit code 2."""
    try:
        return body()
    except SikError as exc:
        print(f'{prog}: error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f'{prog}: interrupted', file=sys.stderr)
        return 130


def argv_or_default(argv: Optional[List[str]]) -> List[str]:
    """The arguments to parse: ``argv`` or the process's."""
    return sys.argv[1:] if argv is None else list(argv)
