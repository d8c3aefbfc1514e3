"""
The floating-point ROS parameters of the ``fault_monitor`` node and the check of a change.

:data:`FLOATS` is the one table the node declares them from (default, description with unit,
range, settable at run time); :data:`RUNTIME` names those the on-set callback accepts, and
:func:`check_runtime_value` gives the reason it refuses a value (the node's module notes,
"Parameters").
"""

from __future__ import annotations

import math

#: Floating-point parameters: name -> (default, description with unit, lowest, highest,
#: settable at run time). The one table for the declaration and both validations.
FLOATS: dict[str, tuple[float, str, float, float, bool]] = {
    "calibration_revs": (16.0, "healthy calibration window, revolutions", 1.0, 1e4, False),
    "k": (8.0, "robust standard deviations of the thresholds", 1.0, 100.0, False),
    "threshold_floor": (2.0e-8, "smallest threshold, m", 0.0, 1e-3, False),
    "decision_revs": (16.0, "longest wait from alarm to decision, revolutions", 0.5, 1e3, False),
    "decision_max_revs": (
        32.0,
        "longest wait while the 1 x level still moves far from its reference, revolutions "
        "(>= decision_revs)",
        0.5,
        1e3,
        False,
    ),
    "quiet_revs": (2.0, "hold-off: quiet revolutions that end an episode", 0.25, 1e3, False),
    "tail_rise_median": (
        3.0,
        "contact burst: finest-level ratio (or its change) over its median since the episode "
        "began",
        1.0,
        100.0,
        False,
    ),
    "control_step": (
        2.0,
        "control step: change of the applied wavelet force on an axis from one revolution to "
        "the next, N",
        1e-3,
        1e5,
        True,
    ),
    "trip_displacement": (
        0.0, "radial trip level, m (0 = from the rig clearances)", 0.0, 0.1, True,
    ),
    "trip_displacement_fraction": (
        2.0 / 3.0, "default radial trip level as a share of the nearest clearance", 0.01, 1.0, True,
    ),
    "trip_1x": (
        0.0, "1 x orbit semi-major axis trip level, m (0 = from the rig)", 0.0, 0.1, True,
    ),
    "trip_1x_fraction": (
        0.5, "default 1 x trip level as a share of the nearest clearance", 0.01, 1.0, True,
    ),
    "trip_hysteresis": (0.1, "trip clears below level * (1 - this)", 0.0, 0.99, True),
    "status_period": (1.0, "period of the /diagnostics report, s (wall clock)", 0.05, 60.0, True),
    "blackbox_pre_s": (2.0, "black box: seconds kept before an event", 0.0, 600.0, False),
    "blackbox_post_s": (1.0, "black box: seconds recorded after an event", 0.0, 600.0, False),
}  # fmt: skip
#: Parameters the on-set callback accepts (all others are read-only).
RUNTIME = tuple(name for name, spec in FLOATS.items() if spec[4])


def check_runtime_value(name: str, value: object) -> str | None:
    """Return why a run-time value of parameter ``name`` is refused, or None if it is valid."""
    _default, desc, lo, hi, _settable = FLOATS[name]
    if not (isinstance(value, float) and math.isfinite(value) and lo <= value <= hi):
        return f"parameter '{name}' = {value!r}: expected {lo:g}..{hi:g} ({desc})"
    return None
