"""
Names of the rig's measurement channels and bearing axes, in message order.

One home for the orders every ``Measurement`` and ``ControlCommand`` use (ARCHITECTURE.md,
README's bridge contract): sensors ``[x1, y1, ..., x4, y4]``, planes numbered from the
non-driven end (thesis figure 2.1); bearing axes ``[b1x, b1y, b2x, b2y]``.
"""

from __future__ import annotations

__all__ = ["AXIS_NAMES", "N_AXES", "N_SENSORS", "SENSOR_NAMES"]

#: Displacement channels (4 sensor planes x 2 directions).
SENSOR_NAMES = ("x1", "y1", "x2", "y2", "x3", "y3", "x4", "y4")
#: AMB control axes (2 bearings x 2 directions).
AXIS_NAMES = ("b1x", "b1y", "b2x", "b2y")
N_SENSORS = len(SENSOR_NAMES)
N_AXES = len(AXIS_NAMES)
