"""
Exceptions raised by the controller core.

Every error subclasses :class:`ValueError` or :class:`TypeError` so that callers (the ROS
node, the closed-loop runner) can catch them with the built-in types; each message states
the expected value, the actual one and how to recover.
"""

from __future__ import annotations


class ControllerValueError(ValueError):
    """A controller argument has a valid type but an invalid value."""


class ShapeError(ControllerValueError):
    """An array argument has the wrong shape."""


class PeriodSequenceError(ControllerValueError):
    """A period index arrived out of order or with a gap."""


class NotIdentifiedError(ControllerValueError):
    """An estimate was requested before enough data had been collected."""


def check_shape(name: str, array, shape: tuple) -> None:
    """
    Raise :class:`ShapeError` unless ``array.shape`` matches ``shape``.

    Parameters
    ----------
    name : str
        Argument name used in the message.
    array : numpy.ndarray
        Array to check.
    shape : tuple of int or None
        Expected shape; ``None`` entries match any length.

    """
    actual = tuple(array.shape)
    if len(actual) != len(shape) or any(
        e is not None and e != a for e, a in zip(shape, actual, strict=True)
    ):
        expected = tuple("any" if e is None else e for e in shape)
        raise ShapeError(
            f"{name} must have shape {expected}, got {actual}; reshape the input or check "
            "the coefficient layout it was built with"
        )
