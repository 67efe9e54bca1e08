"""Checks of values that come from outside: numbers, vectors, quaternions, options.

Every check raises :class:`~sik_ros.errors.InvalidArgument` (or the subclass it is given) with a
message naming the field, and never lets NumPy's or SciPy's own errors through.
"""

import math
from typing import Optional, Type

import numpy as np

from sik_ros.errors import InvalidArgument

#: Largest distance from the base a position may lie at [m]: far beyond any arm's reach, and
#: small enough that squares and norms stay finite.
MAX_DISTANCE = 100.0


def real_array(value, what: str, error: Type[InvalidArgument] = InvalidArgument,
               expected: str = 'numbers') -> np.ndarray:
    """``value`` as a float array; complex values are refused, not cast to their real parts.

    Raises:
        error: not convertible to floats, or complex (``what`` must be ``expected``).
    """
    try:
        raw = np.asarray(value)
        if np.iscomplexobj(raw):
            raise error(f'{what} must be real, not complex; got {value!r}')
        return np.asarray(raw if raw.dtype != object else value, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        if isinstance(exc, InvalidArgument):
            raise
        raise error(f'{what} must be {expected}; got {value!r}') from exc


def vector(value, size: int, what: str, error: Type[InvalidArgument] = InvalidArgument,
           limit: Optional[float] = None) -> np.ndarray:
    """``value`` as ``size`` finite floats (each within +-``limit`` when given)."""
    arr = real_array(value, what, error, f'{size} numbers')
    if arr.shape != (size,):
        raise error(f'{what} must have {size} elements; got shape {arr.shape}')
    # a few numbers: checked as Python floats (NumPy's checks are dear when its code is out
    # of the caches, as at a node's requests)
    values = arr.tolist()
    if not all(math.isfinite(v) for v in values):
        raise error(f'{what} must be finite; got {values}')
    if limit is not None and any(abs(v) > limit for v in values):
        raise error(f'{what} must lie within {limit:g} m of the origin; got {values}')
    return arr


def quaternion(value, what: str, error: Type[InvalidArgument] = InvalidArgument) -> np.ndarray:
    """A unit quaternion x y z w from 4 finite numbers, not all zero (scaled safely)."""
    quat = vector(value, 4, f'{what} quaternion (x, y, z, w)', error)
    values = quat.tolist()
    scale = max(abs(v) for v in values)
    if scale == 0 or scale < 1e-150:
        raise error(f'{what} quaternion is zero')
    x, y, z, w = (v / scale for v in values)  # no overflow in the norm
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    return np.array([x / norm, y / norm, z / norm, w / norm])


def seconds(value, what: str) -> Optional[float]:
    """None, or a number of seconds >= 0 (NaN, infinities and negatives refused)."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InvalidArgument(f'{what} must be a number of seconds or None; got {value!r}')
    value = float(value)
    if not math.isfinite(value) or value < 0:
        raise InvalidArgument(f'{what} must be finite and >= 0 [s]; got {value}')
    return value


def positive(value, what: str) -> float:
    """A finite number > 0, or :class:`InvalidArgument`."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value) or value <= 0:
        raise InvalidArgument(f'{what} must be a finite number > 0; got {value!r}')
    return float(value)


def flag(value, what: str) -> bool:
    """A bool (NumPy's included), or :class:`InvalidArgument`."""
    if not isinstance(value, (bool, np.bool_)):
        raise InvalidArgument(f'{what} must be True or False; got {value!r}')
    return bool(value)
