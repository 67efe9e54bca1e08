"""The paper's pipeline for an arm, in the background of a node: collect, train, index, check.

:class:`BackgroundLearner` runs ``sik-build`` for an arm's cache entry in a process of its own, at
the lowest priority (``nice`` 19) on one core (``sik-build --background`` calls
:func:`in_background` first), its training models one after the other (``--cores 1``), with
checkpoints in the entry's ``build/`` folder (a restarted node resumes the build). Only one process
builds an entry at a time (the entry's lock); another one waits for its bundle.
:meth:`BackgroundLearner.poll` says where the build stands and hands over the finished bundle once;
the caller swaps it in.
"""

import ctypes
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import time
from typing import Callable, Dict, Optional

from sik_ros.bundles.cache import ArmEntry

#: Seconds ``sik-build`` gets to save its checkpoints and exit when the node stops.
STOP_GRACE = 10.0
#: Self-check targets per goal kind of a background build.
CHECK_TARGETS = 50
#: Linux's prctl option: a signal for the child when its parent dies.
PR_SET_PDEATHSIG = 1


def in_background() -> None:
    """In the build process, first: lowest priority, one core, gone with its parent.

    Its training processes inherit the priority and the core.
    """
    os.nice(19)
    try:
        cores = sorted(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cores[-1]})
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        pass
    try:
        ctypes.CDLL('libc.so.6', use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    except OSError:  # pragma: no cover - not Linux
        pass


class BackgroundLearner:
    """One arm's build in the background (see the module).

    Not thread-safe: one caller polls it (the node's timer).
    """

    def __init__(self, entry: ArmEntry, base: str, tip: str, seconds: float, rows: int,
                 log: Callable[[str], None] = print):
        self.entry, self.base, self.tip = entry, base, tip
        self.seconds, self.rows, self.log = float(seconds), int(rows), log
        self._proc: Optional[subprocess.Popen] = None
        self._lock = None
        self._failures = 0
        self._delivered = False
        self.state = 'waiting'
        self.detail = ''

    # -- the build process -----------------------------------------------------------------

    def _command(self):
        return [sys.executable, '-m', 'sik_ros.cli.build', '--background',
                '--urdf', str(self.entry.urdf), '--base', self.base, '--tip', self.tip,
                '--out', str(self.entry.bundle), '--work', str(self.entry.work),
                '--time', f'{self.seconds:g}', '--rows', str(self.rows), '--cores', '1',
                '--check-targets', str(CHECK_TARGETS), '--quiet']

    def _start(self) -> bool:
        """Take the entry's lock and start the build; False when another process holds it."""
        self._lock = self.entry.try_lock()
        if self._lock is None:
            return False
        if self.entry.bundle.exists() and not self.entry.ready():
            # an unfinished bundle left by a builder that died: sik-build resumes from its work
            # folder only when that folder says the bundle stage was done
            state = self.entry.work / 'state.json'
            if not state.is_file() or '"bundle"' not in state.read_text():
                shutil.rmtree(self.entry.bundle, ignore_errors=True)
        env = dict(os.environ, OMP_NUM_THREADS='1', MKL_NUM_THREADS='1')
        self.entry.work.mkdir(parents=True, exist_ok=True)
        with open(self.entry.path / 'build.log', 'ab') as out:
            # a session of its own: stopping it reaches its training processes too
            self._proc = subprocess.Popen(self._command(), stdout=out, stderr=subprocess.STDOUT,
                                          stdin=subprocess.DEVNULL, env=env,
                                          start_new_session=True)
        self.state = 'building'
        self.log(f'learning this arm in the background (pid {self._proc.pid}, {self.seconds:.0f} '
                 f's on one core at low priority; log {self.entry.path / "build.log"})')
        return True

    def _release(self) -> None:
        lock, self._lock = self._lock, None
        if lock is not None:
            self.entry.unlock(lock)

    # -- polling ---------------------------------------------------------------------------

    def poll(self) -> Optional[Path]:
        """Advance the build; the finished bundle's folder, once (then None again)."""
        if self._delivered or self.state == 'failed':
            return None
        if self._proc is None:
            if self.entry.checked_bundle() is not None:
                return self._deliver()
            if not self._start():
                self.state, self.detail = 'waiting', 'another process is building this arm'
            return None
        code = self._proc.poll()
        if code is None:
            return None
        self._proc = None
        self._release()
        if code == 0 and self.entry.checked_bundle() is not None:
            shutil.rmtree(self.entry.work, ignore_errors=True)
            return self._deliver()
        self._failures += 1
        tail = self._log_tail()
        if self._failures >= 2:
            self.state, self.detail = 'failed', f'sik-build exited {code}: {tail}'
            self.log(f'background learning failed twice; serving the table of configurations '
                     f'({self.detail})')
            return None
        # a build begun with other settings (or damaged): start it again from nothing
        self.log(f'background build exited {code} ({tail}); starting it again')
        shutil.rmtree(self.entry.work, ignore_errors=True)
        return None

    def _deliver(self) -> Path:
        self._delivered = True
        self.state, self.detail = 'done', ''
        return self.entry.bundle

    def _log_tail(self) -> str:
        try:
            lines = (self.entry.path / 'build.log').read_text(errors='replace').splitlines()
        except OSError:
            return ''
        return next((ln for ln in reversed(lines) if ln.strip()), '')[-200:]

    def status(self) -> Dict[str, str]:
        """Where the build stands, for ``/diagnostics``: stage, percent, time left."""
        out = {'learning': self.state}
        if self.state == 'building':
            progress = self.entry.status()
            if progress:
                out.update(learning_stage=str(progress.get('stage', '')),
                           learning_percent=f'{float(progress.get("percent", 0.0)):.1f}',
                           learning_seconds_left=f'{float(progress.get("seconds_left", 0)):.0f}')
        if self.detail:
            out['learning_detail'] = self.detail
        return out

    def stop(self) -> None:
        """Stop the build (it saves its checkpoints: the next start resumes it)."""
        proc, self._proc = self._proc, None
        if proc is not None and proc.poll() is None:
            try:
                os.killpg(proc.pid, signal.SIGINT)
            except ProcessLookupError:  # pragma: no cover - it has just exited
                pass
            deadline = time.monotonic() + STOP_GRACE
            while proc.poll() is None and time.monotonic() < deadline:
                time.sleep(0.05)
            if proc.poll() is None:
                try:
                    os.killpg(proc.pid, signal.SIGKILL)
                except ProcessLookupError:  # pragma: no cover
                    pass
                proc.wait()
        self._release()
        if self.state == 'building':
            self.state = 'stopped'
