"""``~/markers`` drawn off the answers' path: a thread of its own, the newest answer first.

Drawing an answer's postures for RViz (forward kinematics of every solution, a few dozen
``Marker`` messages and their serialisation) costs more than the answer's own messages. The
services and the goal stream hand what they answered to :class:`MarkerDrawer` once the answer
is on its way (:func:`~sik_ros.ros.executor.after_answer`); its thread draws the newest one
(:class:`~sik_ros.serving.stream.LatestGoal`: one waiting is replaced, never drawn), so a burst
of requests costs one drawing, after their answers, and drawings are at least
:data:`MIN_PERIOD` apart.
"""

import threading
import time
from typing import Any, Callable, Optional

from sik_ros.serving.stream import LatestGoal

#: Longest wait of the drawing thread before it looks whether it must stop [s].
WAIT = 0.5
#: Shortest time between two drawings [s]: answers handed over meanwhile wait (the newest
#: replacing the others), so the drawing thread holds the GIL a bounded share of the time.
MIN_PERIOD = 1.0 / 30.0


class MarkerDrawer:
    """A thread that draws the newest answer handed over."""

    def __init__(self, on_error: Callable[[str], None]) -> None:
        """Start the thread.

        Args:
            on_error: reports a drawing that failed (the thread goes on).
        """
        self._on_error = on_error
        self.mailbox: LatestGoal = LatestGoal()
        self._stop = threading.Event()
        #: answers drawn since start
        self.drawn = 0
        self._thread = threading.Thread(target=self._serve, name='sik_markers', daemon=True)
        self._thread.start()

    def put(self, draw: Callable[..., None], *args: Any) -> None:
        """Hand an answer over: ``draw(*args)`` builds and publishes its markers.

        One handed over before and not yet drawn is replaced (never drawn).
        """
        self.mailbox.put((draw, args))

    def _serve(self) -> None:
        while not self._stop.is_set():
            taken: Optional[tuple] = self.mailbox.take(WAIT)
            if taken is None or self._stop.is_set():
                continue
            start = time.monotonic()
            try:
                draw, args = taken[0]
                draw(*args)
                self.drawn += 1
            except Exception as exc:  # markers must never cost the node
                self._on_error(f'markers: drawing failed: {type(exc).__name__}: {exc}')
            self._stop.wait(MIN_PERIOD - (time.monotonic() - start))

    def close(self) -> None:
        """Stop the thread (it finishes the drawing in hand)."""
        self._stop.set()
        self.mailbox.close()
        self._thread.join(timeout=2.0)
