"""A call's deadline: one object for every "is there time left?" check.

A :class:`Deadline` holds a ``time.perf_counter()`` value [s] after which a call starts no more
work (``inf``: none). The compiled kernels read the same clock
(:mod:`sik_ros.kernels.clock`) and take the bare value, :attr:`Deadline.at`.
"""

from dataclasses import dataclass
import math
import time
from typing import Optional


@dataclass(frozen=True)
class Deadline:
    """When a call stops starting work.

    Attributes:
        at: a ``time.perf_counter()`` value [s]; ``inf`` for no deadline.
    """

    at: float = math.inf

    @classmethod
    def after(cls, timeout: Optional[float], start: Optional[float] = None) -> 'Deadline':
        """``timeout`` [s] after ``start`` (a ``time.perf_counter()`` value; default now).

        None: no deadline.
        """
        if timeout is None:
            return NO_DEADLINE
        return cls((time.perf_counter() if start is None else start) + timeout)

    @property
    def bounded(self) -> bool:
        """Whether there is a deadline at all."""
        return self.at < math.inf

    def expired(self) -> bool:
        """Whether the deadline has passed."""
        return self.at < math.inf and time.perf_counter() > self.at

    def remaining(self) -> float:
        """Seconds left [s] (negative once passed; ``inf`` without a deadline)."""
        return self.at - time.perf_counter() if self.bounded else math.inf


#: No deadline.
NO_DEADLINE = Deadline()
