"""The one place where numpy arrays become ``amb_msgs`` messages and back.

Generated messages hold ``float64[N]`` fields as numpy arrays and ``float64[]`` fields as
``array.array('d')``. Filling a ``float64[]`` from ``array.array('d', x.tobytes())`` costs about
a microsecond, element-wise assignment from numpy about 57 µs per 1000 values, so every
conversion goes through :func:`to_float_array`. Readers use :func:`from_float_array`
(``np.frombuffer``, no copy). Checks here raise :class:`MessageError` (a ``ValueError``) with
the field, the expected and the actual value, so a node can count and report a bad message
instead of propagating it.
"""

from __future__ import annotations

from array import array

import numpy as np
from builtin_interfaces.msg import Time

NUM_SENSORS = 8
NUM_AXES = 4
SENSOR_NAMES = ("x1", "y1", "x2", "y2", "x3", "y3", "x4", "y4")
AXIS_NAMES = ("b1x", "b1y", "b2x", "b2y")


class MessageError(ValueError):
    """A message field is malformed (length, value range, non-finite value)."""


def to_float_array(values: np.ndarray) -> array:
    """Return ``values`` as ``array('d')`` for a ``float64[]`` field (fast path)."""
    return array("d", np.ascontiguousarray(values, dtype=np.float64).tobytes())


def from_float_array(field: array | np.ndarray) -> np.ndarray:
    """Return a ``float64[]`` or ``float64[N]`` field as a read-only numpy view."""
    return np.frombuffer(field, dtype=np.float64) if isinstance(field, array) else field


def stamp(t: float) -> Time:
    """Return simulated time ``t`` (s, >= 0) as a ``builtin_interfaces/Time``."""
    ns = round(t * 1e9)
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def stamp_seconds(msg_stamp: Time) -> float:
    """Return a ``builtin_interfaces/Time`` in s."""
    return msg_stamp.sec + msg_stamp.nanosec * 1e-9


def check_finite(name: str, values: np.ndarray) -> np.ndarray:
    """Raise :class:`MessageError` unless every value is finite; return ``values``."""
    if not np.all(np.isfinite(values)):
        bad = int(np.count_nonzero(~np.isfinite(values)))
        raise MessageError(f"field '{name}' has {bad} non-finite value(s) (NaN or inf)")
    return values


def check_length(name: str, values: np.ndarray, expected: int) -> np.ndarray:
    """Raise :class:`MessageError` unless ``len(values) == expected``; return ``values``."""
    if len(values) != expected:
        raise MessageError(f"field '{name}' has {len(values)} values, expected {expected}")
    return values
