"""
Scenario files: running speed (by value or by role), duration, events.

Format (YAML, SI units; see ``config/scenarios/*.yaml``)::

    name: mass_loss_first_critical          # identifier
    description: free text
    speed: {role: first_critical}           # or {hz: 22.0}; roles: first_critical,
                                            # second_critical, third_critical, fourth_critical
    speed_profile:                          # optional run-up/run-down (replaces constant speed)
      - {time: 0.0, hz: 5.0}                # piecewise-linear speed vs time; speeds may also be
      - {time: 10.0, role: second_critical} # given by role; must stay > 0
    duration: 4.0                           # s of simulated time
    samples_per_rev: 64                     # optional default for the simulator
    measurement_noise: 1.0e-7               # optional, m, standard deviation on all 8 channels
    events:                                 # see amb_plant_sim.events for every kind
      - {kind: unbalance, time: 0.0, disk: D1, me: 1.0e-4, angle: 0.0}
      - {kind: mass_loss, time: 1.0, disk: D1, me: 4.3e-3, angle: 0.0}

Roles resolve from the model (:func:`amb_plant_sim.modal.critical_speeds`: the running
speeds at which a forward-whirl natural frequency of the PID closed loop equals the speed), so
that experiments run at the model's own critical speeds, as the thesis runs at the rig's.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from amb_common.rig import Rig
from amb_plant_sim.errors import ScenarioError
from amb_plant_sim.events import Event, event_from_dict

ROLES = ("first_critical", "second_critical", "third_critical", "fourth_critical")


@dataclass(frozen=True)
class SpeedSpec:
    """A speed given by value (``hz``) or by role (``role``)."""

    hz: float | None = None
    role: str | None = None

    def resolve(self, critical_hz: list[float] | None) -> float:
        """Speed in Hz; ``critical_hz`` are the model's critical speeds (for roles)."""
        if self.hz is not None:
            return self.hz
        if critical_hz is None:
            raise ScenarioError(f"speed role {self.role!r} needs the rig to resolve; pass rig=")
        return float(critical_hz[ROLES.index(self.role)])


def _speed_spec(d: Any, where: str) -> SpeedSpec:
    if isinstance(d, (int, float)):
        d = {"hz": d}
    if not isinstance(d, dict) or ("hz" in d) == ("role" in d):
        raise ScenarioError(f"{where}: give exactly one of 'hz' (Hz) or 'role', got {d!r}")
    if "role" in d:
        if d["role"] not in ROLES:
            raise ScenarioError(f"{where}: unknown role {d['role']!r}; expected one of {ROLES}")
        return SpeedSpec(role=str(d["role"]))
    hz = float(d["hz"])
    if not (math.isfinite(hz) and hz > 0):
        raise ScenarioError(f"{where}: speed must be > 0 Hz, got {hz}")
    return SpeedSpec(hz=hz)


@dataclass(frozen=True)
class Scenario:
    """
    A simulation scenario.

    Attributes
    ----------
    name : str
    speed : SpeedSpec
        Constant running speed (or the first point of the profile).
    duration : float
        Simulated time, s.
    events : tuple of Event
    profile : tuple of (float, SpeedSpec)
        Piecewise-linear speed profile ``(time s, speed)``; empty for constant speed.
    samples_per_rev : int or None
    measurement_noise : float
        Standard deviation, m.
    speed_hz : float or None
        Resolved constant speed (Hz) once :meth:`resolved` was called.
    profile_hz : tuple of (float, float)
        Resolved profile points (time s, Hz).
    """

    name: str
    speed: SpeedSpec
    duration: float
    events: tuple[Event, ...] = ()
    profile: tuple[tuple[float, SpeedSpec], ...] = ()
    samples_per_rev: int | None = None
    measurement_noise: float = 0.0
    description: str = ""
    speed_hz: float | None = None
    profile_hz: tuple[tuple[float, float], ...] = field(default=())

    def resolved(self, rig: Rig, critical_hz: list[float] | None = None) -> Scenario:
        """
        Copy with speeds resolved against ``rig`` (roles -> model critical speeds).

        ``critical_hz`` (Hz, from :func:`amb_plant_sim.modal.critical_speeds`) may be passed
        to avoid recomputing them for many scenarios of one rig.
        """
        roles = [self.speed.role] + [s.role for _, s in self.profile]
        crit = critical_hz
        if crit is None and any(r is not None for r in roles):
            # heavy, optional: the FE model and scipy.linalg (~0.2 s), only for speeds given by
            # role; amb-run and the launch file load scenarios without them
            from amb_plant_sim.modal import critical_speeds

            crit = critical_speeds(rig, count=len(ROLES))
        prof = tuple((t, s.resolve(crit)) for t, s in self.profile)
        return replace(self, speed_hz=self.speed.resolve(crit), profile_hz=prof)

    def speed_at(self, t: float) -> float:
        """Running speed (Hz) at time ``t`` (s); needs :meth:`resolved`."""
        if self.speed_hz is None:
            raise ScenarioError("scenario speeds are not resolved; call scenario.resolved(rig)")
        if not self.profile_hz:
            return self.speed_hz
        ts = np.array([p[0] for p in self.profile_hz])
        fs = np.array([p[1] for p in self.profile_hz])
        return float(np.interp(t, ts, fs))


def scenario_from_dict(
    d: dict[str, Any], rig: Rig | None = None, critical_hz: list[float] | None = None
) -> Scenario:
    """
    Build (and, with ``rig``, resolve) a scenario from a mapping.

    Raises
    ------
    ScenarioError
        On any invalid field, with the field named.
    """
    if not isinstance(d, dict):
        raise ScenarioError(f"scenario: expected a mapping, got {type(d)}")
    if "speed" not in d and "speed_profile" not in d:
        raise ScenarioError("scenario: give 'speed' ({hz: ...} or {role: ...}) or 'speed_profile'")
    profile: tuple[tuple[float, SpeedSpec], ...] = ()
    if "speed_profile" in d:
        pts = d["speed_profile"]
        if not isinstance(pts, list) or len(pts) < 2:
            raise ScenarioError("scenario: speed_profile needs a list of >= 2 {time, hz|role}")
        profile = tuple(
            (float(p["time"]), _speed_spec({k: v for k, v in p.items() if k != "time"}, "profile"))
            for p in pts
        )
        times = [p[0] for p in profile]
        if any(b <= a for a, b in itertools.pairwise(times)) or times[0] != 0.0:
            raise ScenarioError(
                f"scenario: profile times must start at 0 and increase, got {times}"
            )
    speed = _speed_spec(d["speed"], "speed") if "speed" in d else profile[0][1]
    duration = float(d.get("duration", 0.0))
    if not duration > 0:
        raise ScenarioError(f"scenario: duration must be > 0 s, got {duration}")
    spr = d.get("samples_per_rev")
    if spr is not None:
        spr = int(spr)
        if spr < 2 or spr & (spr - 1):
            raise ScenarioError(f"scenario: samples_per_rev must be a power of two, got {spr}")
    noise = float(d.get("measurement_noise", 0.0))
    if noise < 0:
        raise ScenarioError(f"scenario: measurement_noise must be >= 0 m, got {noise}")
    events = tuple(event_from_dict(e) for e in d.get("events", []) or [])
    sc = Scenario(
        name=str(d.get("name", "scenario")),
        speed=speed,
        duration=duration,
        events=events,
        profile=profile,
        samples_per_rev=spr,
        measurement_noise=noise,
        description=str(d.get("description", "")),
    )
    return sc.resolved(rig, critical_hz) if rig is not None else sc


#: Samples per revolution when neither the caller nor the scenario names them.
DEFAULT_SAMPLES_PER_REV = 64


def resolve_samples_per_rev(requested: int | None, scenario: Scenario) -> int:
    """
    Samples per revolution of a run: the caller's, else the scenario's, else 64.

    One rule for the plant node (its ``samples_per_rev`` parameter, 0 = not set), ``amb-sim``
    (``--samples-per-rev``), ``amb-run`` and the launch file (which pass the scenario's value to
    every node, :func:`amb_apps.system.run_parameters`).

    Parameters
    ----------
    requested : int or None
        Explicit choice (0 or None: none).
    scenario : Scenario
        Its ``samples_per_rev`` (None: not set).

    Returns
    -------
    int
    """
    return int(requested or scenario.samples_per_rev or DEFAULT_SAMPLES_PER_REV)


def load_scenario(
    path: str | Path, rig: Rig | None = None, critical_hz: list[float] | None = None
) -> Scenario:
    """
    Load a scenario YAML file (format in the module docstring).

    Parameters
    ----------
    path : str or Path
        Scenario file.
    rig : Rig, optional
        When given, speed roles are resolved against its model immediately.
    critical_hz : list of float, optional
        Precomputed critical speeds of ``rig`` (Hz).

    Returns
    -------
    Scenario
    """
    p = Path(path)
    if not p.is_file():
        raise ScenarioError(f"scenario file not found: {p}")
    try:
        with p.open(encoding="utf-8") as fh:
            data = yaml.safe_load(fh)
    except yaml.YAMLError as exc:
        raise ScenarioError(f"scenario {p}: not readable YAML: {exc}") from exc
    return scenario_from_dict(data, rig, critical_hz)
