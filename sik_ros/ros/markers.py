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

import numpy as np
from std_msgs.msg import Header

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


class MarkerOutput:
    """The node's ``~/markers``: whether they are wanted, and answers handed to the drawer.

    ``wanted()`` (the node's: ``publish_markers`` on and not closing) and someone listening;
    the drawings themselves are :class:`MarkerDrawer`'s, on its thread.
    """

    def __init__(self, publisher, wanted: Callable[[], bool],
                 on_error: Callable[[str], None]) -> None:
        """Publish on ``publisher`` (a ``MarkerArray`` publisher) while ``wanted()``."""
        self._pub, self._wanted = publisher, wanted
        self.drawer = MarkerDrawer(on_error)

    def want(self) -> bool:
        """Whether markers are wanted now (on, not closing, someone listening)."""
        return self._wanted() and self._pub.get_subscription_count() > 0

    def solutions(self, chain, solutions, header: Header, position: np.ndarray,
                  orientation: Optional[np.ndarray]) -> None:
        """Hand ranked solutions and their goal to the drawer (a newer answer replaces them)."""
        self.drawer.put(self._draw_solutions, chain, solutions, header, position, orientation)

    def path(self, chain, result, header: Header) -> None:
        """Hand a path answer's ranked joint paths to the drawer."""
        self.drawer.put(self._draw_path, chain, result, header)

    def close(self) -> None:
        """Stop the drawing thread."""
        self.drawer.close()

    def _draw_solutions(self, chain, solutions, header, position, orientation) -> None:
        from sik_ros.ros import conversions as conv
        self._pub.publish(conv.posture_markers(chain, solutions, header, position, orientation))

    def _draw_path(self, chain, result, header) -> None:
        from sik_ros.ros.path_service import path_markers
        self._pub.publish(path_markers(chain, result, header))
