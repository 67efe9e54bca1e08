"""Machine-readable benchmark results: the ``--json PATH`` option of the scripts in ``bench/``.

A result file holds a script's figures together with what they were measured with: the exact
command, the date (UTC), the git commit of the code measured and the machine (CPU model, cores,
memory, OS, Python and the versions of the libraries that set the pace). ``bench/render.py``
writes the tables of ``docs/benchmarks.md`` and the README from the files kept in
``docs/results/``, so no figure is typed by hand.

    from report import add_json_argument, write_json   # bench/report.py, beside the script
    add_json_argument(parser)
    ...
    write_json(args.json, 'solve', {'position': {...}, 'pose': {...}})
"""

import argparse
from datetime import datetime, timezone
from importlib import metadata
import json
import math
import os
from pathlib import Path
import platform
import shlex
import subprocess
import sys
from typing import Any, Dict, Optional

#: Version of the file layout below; bump it when a key changes meaning.
SCHEMA = 1
REPO = Path(__file__).resolve().parents[1]
#: Distributions whose versions are recorded with every result.
LIBRARIES = ('numpy', 'scipy', 'torch', 'pin', 'numba', 'pytracik')
#: The load average when the benchmark started (this module is imported at its start): on a
#: shared machine, how busy the cores were says how far the absolute times are from an idle
#: machine's.
LOAD_AT_START = os.getloadavg() if hasattr(os, 'getloadavg') else None


def add_json_argument(parser: argparse.ArgumentParser) -> None:
    """Add ``--json PATH`` to a benchmark's argument parser."""
    parser.add_argument('--json', metavar='PATH',
                        help='also write the figures with the command, date, commit and machine '
                        'to PATH (JSON; docs/results/<benchmark>.json for the docs)')


def _read(path: str) -> str:
    try:
        return Path(path).read_text()
    except OSError:
        return ''


def machine() -> Dict[str, Any]:
    """The machine the figures come from: CPU, cores, memory [GB], OS, libraries, load average.

    The load average is the 1-minute one, at the benchmark's start and when it is written.
    """
    cpu = next((line.split(':', 1)[1].strip() for line in _read('/proc/cpuinfo').splitlines()
                if line.startswith('model name')), platform.processor() or platform.machine())
    mem_kb = next((int(line.split()[1]) for line in _read('/proc/meminfo').splitlines()
                   if line.startswith('MemTotal:')), 0)
    os_name = next((line.split('=', 1)[1].strip().strip('"')
                    for line in _read('/etc/os-release').splitlines()
                    if line.startswith('PRETTY_NAME=')), platform.platform())
    versions = {}
    for name in LIBRARIES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            pass
    cores = len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else os.cpu_count()
    load = os.getloadavg() if hasattr(os, 'getloadavg') else None
    return {'cpu': cpu, 'cores': cores, 'memory_gb': round(mem_kb / 2 ** 20, 1),
            'arch': platform.machine(), 'os': os_name, 'python': platform.python_version(),
            'libraries': versions,
            'load_average': {'start': LOAD_AT_START and round(LOAD_AT_START[0], 2),
                             'end': load and round(load[0], 2)}}


def git_commit(root: Optional[str] = None) -> Dict[str, Any]:
    """The commit of a checkout (default: this one) and whether its code differs from it.

    ``dirty`` is true when tracked files under ``sik_ros/`` (the code measured) or the running
    benchmark script have changes that are not committed: the figures then belong to no commit.
    """
    cwd = str(root or REPO)
    script = Path(sys.argv[0]).resolve()
    paths = ['sik_ros'] + ([str(script.relative_to(REPO))] if root is None and
                           script.is_relative_to(REPO) else [])

    def git(*args: str) -> str:
        run = subprocess.run(['git', *args], cwd=cwd, capture_output=True, text=True)
        return run.stdout.strip() if run.returncode == 0 else ''

    return {'commit': git('rev-parse', '--short=10', 'HEAD') or 'unknown',
            'dirty': bool(git('status', '--porcelain', '--untracked-files=no', '--', *paths))}


def command(argv: Optional[list] = None) -> str:
    """The command that ran, as a user types it from the repository's root."""
    argv = list(sys.argv if argv is None else argv)
    script = Path(argv[0]).resolve()
    try:
        argv[0] = str(script.relative_to(REPO))
    except ValueError:
        argv[0] = script.name
    return 'python ' + shlex.join(argv)


def _clean(value: Any) -> Any:
    """JSON-safe copy: NumPy scalars and arrays as Python values, NaN and inf as null."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if hasattr(value, 'tolist'):  # NumPy scalar or array
        return _clean(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def write_json(path: Optional[str], benchmark: str, results: Any,
               **extra: Any) -> Optional[Path]:
    """Write one result file (nothing when ``path`` is None); returns its path.

    Args:
        path: the file to write; a temporary name is written first, then renamed.
        benchmark: the script's name without ``.py`` (``solve``, ``arms``, ...).
        results: the figures, a JSON-able tree (NumPy values are converted).
        extra: further top-level keys (e.g. ``checkouts`` of an A/B run).
    """
    if not path:
        return None
    data = {'benchmark': benchmark, 'schema': SCHEMA, 'command': command(),
            'date': datetime.now(timezone.utc).strftime('%Y-%m-%dT%H:%M:%SZ'),
            **git_commit(), 'machine': machine(), **_clean(extra), 'results': _clean(results)}
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + '.tmp')
    tmp.write_text(json.dumps(data, indent=1, allow_nan=False) + '\n')
    os.replace(tmp, out)
    return out
