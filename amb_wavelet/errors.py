"""
Exceptions raised by the wavelet core.

All subclass :class:`ValueError` so that callers (the ROS node, the CLI) can catch
one family; each message states what was expected, what was given and how to recover.
"""

from __future__ import annotations

__all__ = ["LevelError", "SampleIndexError", "WaveletNameError"]


class WaveletNameError(ValueError):
    """An unknown wavelet name, or a wavelet that is not orthogonal (e.g. ``bior2.2``)."""


class LevelError(ValueError):
    """A decomposition level outside the range the filterbank or the level map supports."""


class SampleIndexError(ValueError):
    """
    A streaming sample arrived with an unexpected index (gap, repeat or reordering).

    Attributes
    ----------
    expected : int
        Sample index the filterbank was waiting for.
    actual : int
        Sample index that was given.
    """

    def __init__(self, expected: int, actual: int) -> None:
        self.expected = int(expected)
        self.actual = int(actual)
        super().__init__(
            f"sample index {self.actual} given, expected {self.expected} "
            f"({self.actual - self.expected:+d} samples); the filterbank state no longer "
            "matches the signal: call reset(start_sample_index=...) and continue"
        )
