"""Errors of the fault monitor core (all subclass :class:`ValueError`)."""

from __future__ import annotations

__all__ = ["FaultMonitorError", "RecordError"]


class FaultMonitorError(ValueError):
    """Invalid monitor configuration; the message names the field, expected and actual value."""


class RecordError(ValueError):
    """A coefficient record does not fit the monitor (layout, sample order, channel count)."""
