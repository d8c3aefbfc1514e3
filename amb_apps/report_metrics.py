"""``metrics.json`` of a bag with the functions ``amb-sim`` uses (:mod:`amb_controller.metrics`).

The bag's arrays are put in the shape of a :class:`amb_apps.closed_loop.RunResult` and
passed to :func:`amb_controller.metrics.compute_metrics`, so that the report of an ``amb-sim``
bag gives the same numbers as ``amb-sim``'s own ``metrics.json``. What a bag cannot hold is
said in the JSON (``not_in_bag``):

* ``contact_count`` is simulator truth (``MeasurementBlock.truth``), not a measurement: it is
  ``null`` here and ``contact_source`` says why;
* the run configuration ``amb-sim`` adds (the full controller configuration, model source,
  seed, wall time) is not published; ``controller`` holds what the bag does carry (the
  controller name, mode and delay from ``ControllerStatus``, the wavelet and the periods).

Fault time ("after the fault" metrics), in this order: ``--fault-time`` given by the user, the
scenario file (first fault event, as ``amb-sim``), the onset of the first ``FaultEvent`` in the
bag; with none of them the whole run counts as "after the fault" (``fault_time = 0``) and
``fault_time_source`` says so.

Header stamps are whole nanoseconds (``round(t 1e9)``); a sample whose stamp is the fault time
rounded to the nanosecond is taken at the fault time exactly, so that the ``t >= t_f`` test of
:func:`~amb_controller.metrics.compute_metrics` selects the same samples as on the simulator's
time grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from amb_apps.closed_loop import first_fault
from amb_common import topics
from amb_common.names import SENSOR_NAMES
from amb_common.rig import load_rig
from amb_controller.metrics import INNER, compute_metrics
from amb_plant_sim.scenario import load_scenario
from amb_tools.bag_read import BagData

#: amb-sim keys that a bag cannot reproduce, and why.
NOT_IN_BAG = {
    "contact_count": "simulator truth (contact with the clearance bearings is not measured on a "
    "rig and not published); null here",
    "model_source": "the controller's model source is not published",
    "seed": "the simulator's noise seed is not published",
    "wall_time": "amb-sim's run time is not published",
    "model_radius": "the closed-loop radius on the controller's own model is on /diagnostics "
    "(closed_loop_radius) of a node run, not in amb-sim's bag",
    "refused": "a refusal to go ACTIVE is in the ControllerStatus message text, not a field",
    "early_detections": "the early action's decisions are in the controller's log, not published",
    "model_error": "a deliberate model error (amb-sim --model-gain/--model-phase) is amb-sim's "
    "own; the controller's model is not published",
    "radius_without_model_error": "computed by amb-sim from the model without its deliberate "
    "error, which is not published",
    "controller": "only controller name, mode, delay, wavelet and periods are published "
    "(ControllerStatus, ControlCommand, WaveletCoefficients); gains are not",
}


@dataclass
class FaultTime:
    """The fault time used for a bag and where it came from."""

    time: float
    source: str
    candidates: dict = field(default_factory=dict)


@dataclass
class _BagResult:
    """The :class:`~amb_apps.closed_loop.RunResult` fields compute_metrics reads."""

    time: np.ndarray
    displacement: np.ndarray
    wavelet_force: np.ndarray
    bearing_force: np.ndarray
    contact: np.ndarray
    phasor: np.ndarray
    fault_time: float
    samples_per_rev: int
    fault_events: list


def scenario_fault(path: str | Path) -> tuple[float | None, float, str]:
    """Return ``(fault_time or None, speed_hz, name)`` of a scenario file, as ``amb-sim``.

    Parameters
    ----------
    path : str or pathlib.Path
        Scenario YAML (``config/scenarios/``).

    Returns
    -------
    tuple
        Onset of the first fault event in s (``None`` if the scenario has none), running speed
        in Hz (speed role resolved on ``config/rig.yaml``), scenario name.
    """
    scenario = load_scenario(path, load_rig())
    fault = first_fault(scenario)
    return (None if fault is None else float(fault.time)), float(scenario.speed_hz), scenario.name


def choose_fault_time(
    data: BagData, user: float | None = None, scenario: float | None = None
) -> FaultTime:
    """Return the fault time of a bag (order in the module docstring).

    Parameters
    ----------
    data : BagData
    user : float, optional
        s, ``--fault-time``.
    scenario : float, optional
        s, first fault of the scenario file.

    Returns
    -------
    FaultTime
    """
    candidates: dict = {}
    if user is not None:
        candidates["user"] = float(user)
    if scenario is not None:
        candidates["scenario"] = float(scenario)
    if data.fault_events:
        onset = data.fault_events[0]["onset_sample_index"]
        candidates["first_fault_event"] = float(data.sample_time(onset))
    for source in ("user", "scenario", "first_fault_event"):
        if source in candidates and math.isfinite(candidates[source]):
            return FaultTime(candidates[source], source, candidates)
    return FaultTime(
        0.0, "none (no scenario, no FaultEvent, no --fault-time: whole run)", candidates
    )


def bag_metrics(
    data: BagData,
    fault: FaultTime,
    speed_hz: float | None = None,
) -> dict:
    """Return the metrics of a bag, keys and values as ``amb-sim``'s ``metrics.json``.

    Parameters
    ----------
    data : BagData
    fault : FaultTime
    speed_hz : float, optional
        Running speed in Hz (the scenario's, for equality with ``amb-sim``); default the
        median measured speed.

    Returns
    -------
    dict
        :func:`amb_controller.metrics.compute_metrics` keys (``contact_count`` null), with
        ``null`` for what a missing topic prevents, plus ``bag``, ``bag_counts``,
        ``controller``, ``fault_time_source``, ``missing_topics``, ``not_in_bag``.
    """
    spr = data.samples_per_rev or 0
    speed = speed_hz if speed_hz is not None else data.speed_hz()
    meas = data.measurements
    one_x = data.one_x
    out: dict
    if (meas is None and one_x is None) or speed is None or not spr:
        out = {
            "fault_time": fault.time,
            "fault_period": None,
            "revolutions": None,
            "speed_hz": speed,
            "sensors": None,
            "bearings": None,
        }
    else:
        if meas is not None:
            time = meas.time.copy()
            time[meas.stamp_ns == round(fault.time * 1e9)] = fault.time
            x, wf, tf = meas.displacement, meas.wavelet_force, meas.bearing_force
        else:  # placeholders of the right length; the values they give are nulled below
            n = one_x.even.shape[0] * spr
            time = data.sample_time(np.arange(n))
            x, wf, tf = np.zeros((n, 8)), np.zeros((n, 4)), np.zeros((n, 4))
        if one_x is not None:
            phasor = one_x.phasor
        else:
            n_periods = max(1, len(time) // spr)
            phasor = np.zeros((n_periods, 8), dtype=complex)
        result = _BagResult(
            time,
            x,
            wf,
            tf,
            np.zeros((len(time), 0), dtype=bool),
            phasor,
            fault.time,
            spr,
            list(data.fault_events),
        )
        out = compute_metrics(result, speed)
        if meas is None:
            out["bearings"] = None
            if data.commands is not None:  # the wavelet force is what the commands applied
                wf = _applied_command_force(data, len(time))
                out["bearings"] = {
                    str(b + 1): {
                        "peak_wavelet_force": float(np.hypot(wf[:, 2 * b], wf[:, 2 * b + 1]).max()),
                        "peak_total_force": None,
                    }
                    for b in range(2)
                }
            out["inner_revolution_peaks"] = None
            for name in SENSOR_NAMES:
                out["sensors"][name]["peak_after_fault"] = None
                out["sensors"][name]["steady_1x_amplitude"] = None
        if one_x is None:
            for name in SENSOR_NAMES:
                out["sensors"][name]["settling_revolutions"] = None
    out["contact_count"] = None
    out["contact_source"] = "not in the bag: " + NOT_IN_BAG["contact_count"]
    out["fault_events"] = list(data.fault_events)
    out.update(
        {
            "bag": str(data.path),
            "bag_counts": {
                t: n
                for t, n in data.counts.items()
                if t.startswith(data.topic(topics.PREFIX)) and n
            },
            "controller": _controller(data),
            "fault_time_source": fault.source,
            "fault_time_candidates": fault.candidates,
            "missing_topics": list(data.missing),
            "notes": list(data.notes),
            "not_in_bag": dict(NOT_IN_BAG),
        }
    )
    return out


def _applied_command_force(data: BagData, n_samples: int) -> np.ndarray:
    """
    Return ``(n_samples, 4)`` N: each period's commanded force, as the plant applies it.

    Zero in a period without a command; for a bag without ``/amb/measurement``.
    """
    cmd = data.commands
    n = cmd.force.shape[2]
    wf = np.zeros((n_samples, 4))
    for start, force in zip(cmd.start_sample_index, cmd.force, strict=True):
        if start < n_samples:
            stop = min(n_samples, start + n)
            wf[start:stop] = force.T[: stop - start]
    return wf


def _controller(data: BagData) -> dict:
    d = dict(data.controller)
    if data.commands is not None:
        d.setdefault("delay_periods", data.commands.delay_periods)
        d["wavelet"] = data.commands.wavelet
        d["samples_per_period"] = int(data.commands.force.shape[2])
    elif data.one_x is not None:
        d["wavelet"] = data.one_x.wavelet
    if data.samples_per_rev:
        d["samples_per_rev"] = data.samples_per_rev
    return d


def inner_summary(metrics: dict) -> dict:
    """Return the key figures of a bag's metrics (``None`` where not available).

    Returns
    -------
    dict
        ``steady_1x`` (largest steady 1 x amplitude at x2, y2, x3, y3, m), ``peak`` (largest peak
        after the fault at those sensors, m), ``settling`` (largest settling, revolutions),
        ``peak_wavelet_force`` (largest over both bearings, N), ``peak_total_force`` (N).
    """

    def worst(key):
        s = metrics.get("sensors")
        if not s:
            return None
        vals = [s[SENSOR_NAMES[c]][key] for c in INNER]
        return None if any(v is None for v in vals) else max(vals)

    def largest_force(key):
        b = metrics.get("bearings")
        vals = [] if not b else [v[key] for v in b.values()]
        return None if not vals or any(v is None for v in vals) else max(vals)

    return {
        "steady_1x": worst("steady_1x_amplitude"),
        "peak": worst("peak_after_fault"),
        "settling": worst("settling_revolutions"),
        "peak_wavelet_force": largest_force("peak_wavelet_force"),
        "peak_total_force": largest_force("peak_total_force"),
    }


def json_default(value):
    """``json.dumps`` default for metrics documents: numpy scalars and arrays, else ``str``."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)
