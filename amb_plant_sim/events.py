"""
Disturbance and fault events of chapter 3 and section 5.2, scheduled at a simulated time.

Every event has ``kind``, ``time`` (s, onset; applied at the first sample instant at or after
it) and an optional ``duration`` (s; ``None`` = until the end). Kinds and their fields:

``unbalance`` (residual unbalance) and ``mass_loss`` (sudden unbalance change, eq. 3.3)
    ``disk`` (tag, e.g. ``D1``) or ``z`` (m); ``me`` (kg m, e.g. 430 g cm = 4.3e-3 kg m);
    ``angle`` (rad): phase of the unbalance vector CHANGE relative to the keyphasor angle
    (for a mass lost at angle ``a`` the change points at ``a + pi``; give that angle).
    Force ``me Omega^2 [cos(theta + angle), sin(theta + angle)]`` (eq. 3.3, 5.1).
``sync_force``
    Step synchronous force through an AMB (sections 7.4.1, 8.5.2): ``bearing`` (1 or 2),
    ``amplitude`` (N), ``angle`` (rad). Force ``F [cos(theta + angle), sin(theta + angle)]``.
``step_force``
    Constant force: ``bearing`` (1 or 2) or ``z`` (m); ``fx``, ``fy`` (N).
``misalignment``
    Clearance-bearing centre offset (section 5.2): ``bearing`` (tag, e.g. ``AB1`` or ``R1``),
    ``dx``, ``dy`` (m), ``ramp`` (s, linear ramp to the offset), ``hold`` (s), ``return_time``
    (s, ramp back to zero; 0 = stays).
``base_motion``
    Base acceleration (eq. 3.6): ``direction`` (``x`` or ``y``), ``amplitude`` (m/s^2),
    ``frequency`` (Hz; 0 = a constant step), ``phase`` (rad); lasts ``duration``.
``sensor_fault``
    ``plane`` (1-4), ``axis`` (``x``/``y``), ``mode`` (``offset``, ``stuck``, ``zero``,
    ``noise``), ``value`` (m: offset, or noise standard deviation).
``amb_channel_loss``
    Loss of a coil/amplifier channel: ``axis`` (``b1x``, ``b1y``, ``b2x``, ``b2y``),
    ``coils``: ``both`` (no force on that axis) or ``positive``/``negative`` (one coil of the
    opposing pair left: uncompensated attraction, eq. 2.33 with one term).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from amb_common.names import AXIS_NAMES
from amb_plant_sim.errors import ScenarioError

KINDS = {
    "unbalance": {"me"},
    "mass_loss": {"me"},
    "sync_force": {"bearing", "amplitude"},
    "step_force": set(),
    "misalignment": {"bearing"},
    "base_motion": {"direction", "amplitude"},
    "sensor_fault": {"plane", "axis", "mode"},
    "amb_channel_loss": {"axis"},
}
OPTIONAL = {
    "unbalance": {"disk", "z", "angle"},
    "mass_loss": {"disk", "z", "angle"},
    "sync_force": {"angle"},
    "step_force": {"bearing", "z", "fx", "fy"},
    "misalignment": {"dx", "dy", "ramp", "hold", "return_time"},
    "base_motion": {"frequency", "phase"},
    "sensor_fault": {"value"},
    "amb_channel_loss": {"coils"},
}


@dataclass(frozen=True)
class Event:
    """
    A scheduled disturbance or fault.

    Attributes
    ----------
    kind : str
        One of the kinds in the module docstring.
    time : float
        Onset, s.
    duration : float or None
        Active span, s (``None``: to the end of the run).
    params : dict
        Kind-specific fields (SI units).
    """

    kind: str
    time: float = 0.0
    duration: float | None = None
    params: dict[str, Any] = field(default_factory=dict)

    def active(self, t: float) -> bool:
        """True if the event acts at time ``t`` (s)."""
        if t < self.time - 1e-12:
            return False
        return self.duration is None or t < self.time + self.duration - 1e-12

    def get(self, key: str, default: Any = None) -> Any:
        """Kind-specific field ``key`` (or ``default``)."""
        return self.params.get(key, default)


def _num(v: Any, name: str) -> float:
    try:
        x = float(v)
    except (TypeError, ValueError) as exc:
        raise ScenarioError(f"event field {name} must be a number, got {v!r}") from exc
    if not math.isfinite(x):
        raise ScenarioError(f"event field {name} must be finite, got {x}")
    return x


def event_from_dict(d: dict[str, Any]) -> Event:
    """
    Build and validate an :class:`Event` from a mapping (a scenario entry).

    Raises
    ------
    ScenarioError
        Unknown kind, missing or unknown fields, invalid values.
    """
    if isinstance(d, Event):
        return d
    if not isinstance(d, dict) or "kind" not in d:
        raise ScenarioError(f"an event must be a mapping with a 'kind', got {d!r}")
    kind = str(d["kind"])
    if kind not in KINDS:
        raise ScenarioError(f"unknown event kind {kind!r}; expected one of {sorted(KINDS)}")
    params = {k: v for k, v in d.items() if k not in ("kind", "time", "duration")}
    missing = KINDS[kind] - set(params)
    if missing:
        raise ScenarioError(f"event {kind}: missing field(s) {sorted(missing)}")
    unknown = set(params) - KINDS[kind] - OPTIONAL[kind]
    if unknown:
        raise ScenarioError(
            f"event {kind}: unknown field(s) {sorted(unknown)}; "
            f"allowed {sorted(KINDS[kind] | OPTIONAL[kind])}"
        )
    t = _num(d.get("time", 0.0), "time")
    if t < 0:
        raise ScenarioError(f"event {kind}: time must be >= 0 s, got {t}")
    dur = d.get("duration")
    if dur is not None:
        dur = _num(dur, "duration")
        if dur <= 0:
            raise ScenarioError(f"event {kind}: duration must be > 0 s, got {dur}")
    if kind in ("unbalance", "mass_loss"):
        if "disk" not in params and "z" not in params:
            raise ScenarioError(f"event {kind}: give 'disk' (tag) or 'z' (m)")
        params["me"] = _num(params["me"], "me")
        params["angle"] = _num(params.get("angle", 0.0), "angle")
    elif kind == "sync_force":
        if int(params["bearing"]) not in (1, 2):
            raise ScenarioError(f"sync_force: bearing must be 1 or 2, got {params['bearing']}")
        params["bearing"] = int(params["bearing"])
        params["amplitude"] = _num(params["amplitude"], "amplitude")
        params["angle"] = _num(params.get("angle", 0.0), "angle")
    elif kind == "step_force":
        if "bearing" not in params and "z" not in params:
            raise ScenarioError("step_force: give 'bearing' (1 or 2) or 'z' (m)")
        params["fx"] = _num(params.get("fx", 0.0), "fx")
        params["fy"] = _num(params.get("fy", 0.0), "fy")
    elif kind == "misalignment":
        for k in ("dx", "dy", "ramp", "hold", "return_time"):
            params[k] = _num(params.get(k, 0.0), k)
        if min(params["ramp"], params["hold"], params["return_time"]) < 0:
            raise ScenarioError("misalignment: ramp, hold and return_time must be >= 0 s")
    elif kind == "base_motion":
        if params["direction"] not in ("x", "y"):
            raise ScenarioError(f"base_motion: direction must be x or y, got {params['direction']}")
        params["amplitude"] = _num(params["amplitude"], "amplitude")
        params["frequency"] = _num(params.get("frequency", 0.0), "frequency")
        params["phase"] = _num(params.get("phase", 0.0), "phase")
    elif kind == "sensor_fault":
        plane = int(params["plane"])
        if not 1 <= plane <= 4:
            raise ScenarioError(f"sensor_fault: plane must be 1..4, got {plane}")
        if params["axis"] not in ("x", "y"):
            raise ScenarioError(f"sensor_fault: axis must be x or y, got {params['axis']}")
        if params["mode"] not in ("offset", "stuck", "zero", "noise"):
            raise ScenarioError(
                f"sensor_fault: mode must be offset, stuck, zero or noise, got {params['mode']}"
            )
        params["plane"] = plane
        params["value"] = _num(params.get("value", 0.0), "value")
        if params["mode"] == "noise" and params["value"] < 0:
            raise ScenarioError("sensor_fault noise: value (standard deviation, m) must be >= 0")
    elif kind == "amb_channel_loss":
        if params["axis"] not in AXIS_NAMES:
            raise ScenarioError(
                f"amb_channel_loss: axis must be one of {AXIS_NAMES}, got {params['axis']}"
            )
        coils = params.get("coils", "both")
        if coils not in ("both", "positive", "negative"):
            raise ScenarioError(
                f"amb_channel_loss: coils must be both/positive/negative, got {coils}"
            )
        params["coils"] = coils
    return Event(kind=kind, time=t, duration=dur, params=params)


def sensor_channel(plane: int, axis: str) -> int:
    """Channel index 0..7 of ``plane`` (1..4) and ``axis`` (x/y): [x1, y1, ..., x4, y4]."""
    return 2 * (plane - 1) + (0 if axis == "x" else 1)


def misalignment_offset(ev: Event, t: float) -> tuple[float, float]:
    """Centre offset (m) of a misalignment event at time ``t`` (s): ramp, hold, return."""
    if t < ev.time:
        return 0.0, 0.0
    s = t - ev.time
    ramp, hold, ret = ev.get("ramp"), ev.get("hold"), ev.get("return_time")
    if s < ramp:
        a = s / ramp
    elif ret <= 0.0 or s < ramp + hold:
        a = 1.0
    elif s < ramp + hold + ret:
        a = 1.0 - (s - ramp - hold) / ret
    else:
        a = 0.0
    return a * ev.get("dx"), a * ev.get("dy")


def base_acceleration(ev: Event, t: float) -> float:
    """Base acceleration (m/s^2) of a base-motion event at time ``t`` (s)."""
    if not ev.active(t):
        return 0.0
    f = ev.get("frequency")
    if f == 0.0:
        return ev.get("amplitude")
    return ev.get("amplitude") * math.sin(2 * math.pi * f * (t - ev.time) + ev.get("phase"))
