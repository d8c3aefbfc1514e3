"""
Scenario-suite evaluation of the fault monitor on the simulator (no ROS).

Scenario file format
--------------------
A fault scenario is an ``amb_plant_sim`` scenario file (speed, duration, noise, events: see
:mod:`amb_plant_sim.scenario` and :mod:`amb_plant_sim.events`) with one extra section,
``expect``, that the simulator ignores::

    name: mass_loss_67hz_430gcm_0deg
    speed: {hz: 67.64}                      # 425 rad/s (figures 5.1-5.6)
    duration: 3.0                           # s
    samples_per_rev: 32                     # 0.46 ms at 67 Hz, as section 5.2
    measurement_noise: 0.2e-6               # m
    events:
      - {kind: unbalance, time: 0.0, disk: D1, me: 0.5e-3, angle: 0.0}
      - {kind: mass_loss, time: 2.0, disk: D1, me: 4.3e-3, angle: 0.0}
    expect:                                 # what the monitor must report
      - {fault: MASS_LOSS, time: 2.0}       # true onset, s (the event's time)
      - {fault: AUX_BEARING_CONTACT, from: contact}   # onset = first simulated contact
    monitor: {wavelet: db2}                 # optional MonitorConfig / filterbank overrides

``expect: []`` (or no ``expect``) declares a healthy run: every event is a false alarm. The
``fault`` names are those of :class:`~amb_common.faults.FaultType`. ``from: contact``
takes the true onset from the simulator's truth (first sample after a contact force), so
contact cases need no guessed time; the run must then contain a contact or the case is
reported as ``NO_TRUTH``. To add a case, copy a file, change the events and the
expectation, and run ``amb-fault-eval --scenarios DIR``.

Scoring
-------
An expected fault is matched to the earliest unmatched event of the same class whose onset
lies within ``match_revs`` revolutions after (or one revolution before) the true onset;
failing that to the earliest event of any class in that window (a confusion), failing that it
is ``MISSED``. Events matched to nothing are false alarms. Detection delay is
``detection - true onset``, the onset error ``estimated onset - true onset``. The true onset
of ``from: contact`` is the first sample instant at or after the first contact force > 0
(the simulator's truth, however light the touch; its truth row ``s`` holds the force over
the interval after sample ``s``, so the onset is ``s + 1``, as the first sample instant at or
after the time of a timed fault); the peak force of that first touch is reported with the match. A
fault that comes before the monitor finished calibrating (its healthy window is
``calibration_revs`` plus the support of the deepest level, about 33 revolutions with db4
at 32 samples per revolution) is flagged ``before_calibration`` and counted in the summary:
the scenario, not the method, is then at fault (place faults later).

Speed profiles (run-ups, run-downs: ``speed_profile`` in place of ``speed``) are simulated to
the scenario's ``duration`` (:meth:`PlantSimulator.samples_before
<amb_plant_sim.simulator.PlantSimulator.samples_before>`), times are the simulator's sample
instants (:func:`sample_time`; not ``sample / fs``) and revolutions are samples over
``samples_per_rev``, true at any speed under speed-synchronous sampling; each match carries
the running speed at the true onset (``speed_hz_at_onset``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import ArrayLike

from amb_common.faults import FINAL, PROVISIONAL, WITHDRAWN, FaultEvent, FaultType, event_status
from amb_fault_monitor.config import MonitorConfig
from amb_fault_monitor.errors import FaultMonitorError
from amb_fault_monitor.monitor import FaultMonitor
from amb_fault_monitor.records import FilterbankAdapter
from amb_plant_sim.scenario import scenario_from_dict
from amb_plant_sim.simulator import PlantSimulator
from amb_wavelet.filters import get_filters
from amb_wavelet.levels import support_length

__all__ = [
    "FIRST_ANSWER_REVS",
    "CaseResult",
    "Expectation",
    "SimulatedCase",
    "evaluate_case",
    "first_answers",
    "load_case",
    "run_case",
    "sample_time",
    "simulate_case",
    "summarise",
]

MISSED = "MISSED"
NONE = "NONE"


@dataclass(frozen=True)
class Expectation:
    """An expected fault: class and true onset (s, or from the simulator truth)."""

    fault: FaultType
    time: float | None = None
    source: str = "time"


@dataclass
class CaseResult:
    """Outcome of one scenario."""

    name: str
    path: str
    speed_hz: float
    samples_per_rev: int
    wavelet: str
    duration: float
    matches: list[dict[str, Any]] = field(default_factory=list)
    false_alarms: list[dict[str, Any]] = field(default_factory=list)
    events: list[dict[str, Any]] = field(default_factory=list)
    #: provisional events of episodes whose final event matched no expected fault (and that
    #: were not withdrawn)
    provisional_false_alarms: list[dict[str, Any]] = field(default_factory=list)
    finest_support: int = 2
    wall_time: float = 0.0
    calibration_end_sample: int | None = None
    #: where the monitor calibrated again (after a sensor fault on a feedback probe)
    recalibration_samples: list[int] = field(default_factory=list)


def load_case(path: str | Path) -> tuple[dict[str, Any], list[Expectation], dict[str, Any]]:
    """
    Read a fault scenario file.

    Returns
    -------
    scenario : dict
        The ``amb_plant_sim`` part.
    expect : list of Expectation
    monitor : dict
        Overrides (``wavelet``, ``levels`` and any :class:`MonitorConfig` field).

    Raises
    ------
    FaultMonitorError
        On an unknown fault name or a missing onset.
    """
    p = Path(path)
    with p.open(encoding="utf-8") as fh:
        d = yaml.safe_load(fh)
    if not isinstance(d, dict):
        raise FaultMonitorError(f"{p}: expected a mapping at the top level")
    expect = []
    for e in d.pop("expect", None) or []:
        name = str(e.get("fault", ""))
        if name not in FaultType.__members__:
            raise FaultMonitorError(
                f"{p}: unknown fault {name!r}; expected one of {list(FaultType.__members__)}"
            )
        if "time" in e:
            expect.append(Expectation(FaultType[name], float(e["time"])))
        elif e.get("from") == "contact":
            expect.append(Expectation(FaultType[name], None, "contact"))
        else:
            raise FaultMonitorError(f"{p}: expectation {e} needs 'time' (s) or 'from: contact'")
    monitor = d.pop("monitor", None) or {}
    return d, expect, monitor


def _truth_onset(exp: Expectation, truth: dict, times: np.ndarray, after: float) -> int | None:
    """True onset sample of an expectation; ``times`` are the sample instants (s)."""
    if exp.source == "time":  # the first sample instant at or after the event (its onset)
        return int(np.searchsorted(times, exp.time - 1e-9))
    contact = truth["contact"].any(axis=1)
    idx = np.flatnonzero(contact & (times >= after - 1e-9))
    # truth row s holds the contact force over (t_s, t_s+1]: the sample at t_s was taken
    # before the touch, the first sample at or after it is s + 1 (as for a timed fault)
    return int(idx[0]) + 1 if idx.size else None


def sample_time(times: np.ndarray, sample: ArrayLike) -> Any:
    """
    Instant (s) of sample index ``sample`` (int or array) of a block with instants ``times``.

    Beyond the block (an onset back-dated before sample 0, an index after the last sample) the
    instants are extrapolated with the first or last period. On a speed profile the instants are
    not ``sample / fs``; revolutions are ``samples / samples_per_rev`` at any speed.
    """
    k = np.asarray(sample)
    inside = np.clip(k, 0, times.size - 1)
    before = times[0] + k * (times[1] - times[0])
    after = times[-1] + (k - (times.size - 1)) * (times[-1] - times[-2])
    out = np.where(k < 0, before, np.where(k >= times.size, after, times[inside]))
    return float(out) if out.ndim == 0 else out


def _first_burst_peak(truth: dict, first: int, gap: int = 2) -> float:
    """Largest contact force (N) of the contact burst that starts at sample ``first``."""
    force = truth["contact_force"].max(axis=1)
    end = first
    while end + 1 < force.size and force[end + 1 : end + 1 + gap].max(initial=0.0) > 0:
        end += 1 + int(np.argmax(force[end + 1 : end + 1 + gap] > 0))
    return float(force[first : end + 1].max())


@dataclass
class SimulatedCase:
    """One scenario simulated once (the monitor can then run on it with several wavelets)."""

    path: str
    name: str
    speed_hz: float
    samples_per_rev: int
    duration: float
    expect: list[Expectation]
    monitor: dict[str, Any]
    block: Any
    wall_time: float = 0.0
    rig: Any = None  # the rig simulated, whose monitor runs on it (FaultMonitor.from_rig)


def simulate_case(
    path: str | Path, rig: Any, samples_per_rev: int | None = None, seed: int = 0
) -> SimulatedCase:
    """
    Simulate one scenario with the plant core (no ROS).

    Parameters
    ----------
    path : str or Path
        Fault scenario file (module docstring).
    rig : amb_common.rig.Rig
    samples_per_rev : int, optional
        Overrides the file (default 32).
    seed : int
        Noise seed.

    Returns
    -------
    SimulatedCase
    """
    scen_d, expect, mon_d = load_case(path)
    scenario = scenario_from_dict(scen_d, rig)
    spr = int(samples_per_rev or scenario.samples_per_rev or 32)
    t0 = time.perf_counter()
    sim = PlantSimulator(rig, scenario, spr, seed)
    if scenario.profile_hz:  # every sample before the end (a run-up: more than at its start)
        n = sim.samples_before(scenario.duration)
    else:  # whole samples at the speed, rounded (unchanged for the suite's cases)
        n = round(scenario.duration * spr * scenario.speed_hz)
    block = sim.advance(n)
    return SimulatedCase(
        path=str(path),
        name=scenario.name,
        speed_hz=scenario.speed_hz,
        samples_per_rev=spr,
        duration=scenario.duration,
        expect=expect,
        monitor=mon_d,
        block=block,
        wall_time=time.perf_counter() - t0,
        rig=rig,
    )


def run_case(
    case: SimulatedCase,
    wavelet: str | None = None,
    match_revs: float = 20.0,
    trace: list | None = None,
    provisional_revs: float | None = None,
) -> CaseResult:
    """
    Run the filterbank core and the monitor on a simulated scenario and score the events.

    Parameters
    ----------
    case : SimulatedCase
    wavelet : str, optional
        Overrides the file (default ``haar``).
    match_revs : float
        Matching window after the true onset, revolutions.
    trace : list, optional
        When given, the monitor's feature ratios are appended to it
        (:attr:`FaultMonitor.trace <amb_fault_monitor.monitor.FaultMonitor>`).
    provisional_revs : float, optional
        Overrides the file's ``MonitorConfig.provisional_revs`` (provisional classes).

    Returns
    -------
    CaseResult
        ``calibration_end_sample`` is when the thresholds were first set (and
        ``recalibration_samples`` when they were set again); a match whose true onset comes
        earlier carries ``before_calibration: True`` (the fault fell inside the healthy
        window the monitor needs, which says nothing about the method). A contact match
        carries ``first_contact_peak_n``, the largest force of the first simulated contact
        burst (a graze of a few tens of N may lie below the noise floor). The matches and
        false alarms are scored on the final events; provisional and withdrawn ones
        (``evidence["status"]``) are in ``events`` and give each match its
        ``first_predicted`` and ``first_decision_revs``: the class and decision delay of the
        earliest event of either kind whose onset lies in the match window
        (:func:`first_answers`).
    """
    spr = case.samples_per_rev
    mon_d = case.monitor
    wav = wavelet or mon_d.get("wavelet", "haar")
    names = {f.name for f in fields(MonitorConfig)} - {"samples_per_rev"}
    cfg = MonitorConfig(spr, **{k: v for k, v in mon_d.items() if k in names})
    if "levels" in mon_d:
        cfg = replace(cfg, levels=tuple(mon_d["levels"]))
    if provisional_revs is not None:
        cfg = replace(cfg, provisional_revs=float(provisional_revs))
    block = case.block
    times = block.time  # s, the sample instants (on a speed profile not n / fs)
    t0 = time.perf_counter()
    adapter = FilterbankAdapter(spr, wav)
    monitor = FaultMonitor.from_rig(cfg, case.rig)
    monitor.trace = trace
    events: list[FaultEvent] = []
    for i in range(block.sample_index.size):
        n = int(block.sample_index[i])
        events += monitor.currents(n, block.bearing_force[i], block.current[i], block.omega[i])
        monitor.displacements(n, block.displacement[i])
        rec = adapter.step(n, block.displacement[i], block.angle[i], block.omega[i])
        events += monitor.step(rec)
    wall = time.perf_counter() - t0
    L = get_filters(wav).length
    res = CaseResult(
        name=case.name,
        path=case.path,
        speed_hz=case.speed_hz,
        samples_per_rev=spr,
        wavelet=wav,
        duration=case.duration,
        finest_support=support_length(1, L),
        wall_time=wall,
        calibration_end_sample=monitor.calibrations[0] if monitor.calibrations else None,
        recalibration_samples=monitor.calibrations[1:],
    )
    res.events = [e.to_dict() for e in events]
    every = events
    events = [e for e in every if e.evidence.get("status") not in (PROVISIONAL, WITHDRAWN)]
    used: set[int] = set()
    expect = case.expect
    last_fault_time = max((e.time for e in expect if e.time is not None), default=0.0)
    for exp in expect:
        after = last_fault_time if exp.source != "time" else 0.0
        true = _truth_onset(exp, block.truth, times, after)
        row: dict[str, Any] = {"expected": exp.fault.name, "true_onset_sample": true}
        if true is None:
            row["predicted"] = "NO_TRUTH"
            res.matches.append(row)
            continue
        if true >= times.size:  # the onset falls after the run's last sample
            row["predicted"] = "NO_TRUTH"
            res.matches.append(row)
            continue
        row["true_onset_time"] = float(times[true])
        row["speed_hz_at_onset"] = float(block.omega[true] / (2 * math.pi))
        cal = res.calibration_end_sample
        row["before_calibration"] = cal is None or true < cal
        if exp.source == "contact":
            row["first_contact_peak_n"] = _first_burst_peak(block.truth, true - 1)
        lo, hi = true - spr, true + match_revs * spr
        window = [
            (i, e)
            for i, e in enumerate(events)
            if i not in used and lo <= e.onset_sample_index <= hi
        ]
        same = [w for w in window if w[1].fault_type == exp.fault]
        pick = (same or window or [None])[0]
        if pick is None:
            row["predicted"] = MISSED
        else:
            i, e = pick
            used.add(i)
            row.update(
                predicted=e.fault_type.name,
                count=e.count,
                confidence=e.confidence,
                detection_delay_samples=e.detection_sample_index - true,
                decision_delay_samples=e.decision_sample_index - true,
                onset_error_samples=e.onset_sample_index - true,
                detection_delay_ms=1e3
                * (sample_time(times, e.detection_sample_index) - times[true]),
                detection_delay_revs=(e.detection_sample_index - true) / spr,
                decision_delay_revs=(e.decision_sample_index - true) / spr,
                onset_error_ms=1e3 * (sample_time(times, e.onset_sample_index) - times[true]),
            )
        res.matches.append(row)
    first_answers(res.matches, every, spr, match_revs)
    for i, e in enumerate(events):
        if i not in used:
            res.false_alarms.append(
                {
                    "predicted": e.fault_type.name,
                    "detection_time": sample_time(times, e.detection_sample_index),
                }
            )
    matched = {_episode_key(events[i]) for i in used}
    void = {_episode_key(e) for e in every if e.evidence.get("status") == WITHDRAWN}
    for e in every:
        key = _episode_key(e)
        if e.evidence.get("status") == PROVISIONAL and key not in matched | void:
            res.provisional_false_alarms.append(
                {
                    "predicted": e.fault_type.name,
                    "detection_time": sample_time(times, e.detection_sample_index),
                }
            )
    return res


#: Revolutions after the true onset within which the earliest answer should be right (issue
#: 19: a provisional class a controller can act on).
FIRST_ANSWER_REVS = 2.0


def _episode_key(e: FaultEvent) -> int:
    """An episode's events share its detection (alarm) sample; its onset estimate may move."""
    return e.detection_sample_index


def first_answers(
    matches: list[dict[str, Any]], events: list[FaultEvent], spr: int, match_revs: float
) -> None:
    """
    Give each match the earliest answer, provisional or final (in place).

    Each match with a true onset gets ``first_predicted`` (``MISSED`` for none) and
    ``first_decision_revs``: the earliest event by decision (withdrawn ones left out) whose
    onset lies from one revolution before the true onset to ``match_revs`` after it, as the
    final matching's window, and whose episode (its detection sample: a provisional event and
    its final one share it) was not given to an earlier match.
    """
    given: set[int] = set()
    for row in matches:
        true = row.get("true_onset_sample")
        if true is None or row.get("predicted") == "NO_TRUTH":
            continue
        lo, hi = true - spr, true + match_revs * spr
        window = [
            (e.decision_sample_index, i)
            for i, e in enumerate(events)
            if _episode_key(e) not in given
            and e.evidence.get("status") != WITHDRAWN
            and lo <= e.onset_sample_index <= hi
        ]
        if not window:
            row["first_predicted"] = MISSED
            continue
        decision, i = min(window)
        given.add(_episode_key(events[i]))
        row["first_predicted"] = events[i].fault_type.name
        row["first_decision_revs"] = (decision - true) / spr


def evaluate_case(
    path: str | Path,
    rig: Any,
    samples_per_rev: int | None = None,
    wavelet: str | None = None,
    match_revs: float = 20.0,
    seed: int = 0,
) -> CaseResult:
    """
    Simulate one scenario, run the filterbank core and the monitor, score the events.

    :func:`simulate_case` followed by :func:`run_case` (parameters as there).

    Returns
    -------
    CaseResult
    """
    case = simulate_case(path, rig, samples_per_rev, seed)
    res = run_case(case, wavelet, match_revs)
    res.wall_time += case.wall_time
    return res


def summarise(results: list[CaseResult]) -> dict[str, Any]:
    """
    Confusion matrix, delays, onset errors and false alarms per simulated hour.

    Returns
    -------
    dict
        ``confusion`` (expected -> predicted -> count; ``NONE`` row for false alarms),
        ``delays`` per class (median / max detection delay in ms and revolutions, decision
        delay in revolutions, onset error in ms and in finest-level supports),
        ``false_alarms_per_hour``, ``simulated_s``, ``correct``, ``total``,
        ``before_calibration`` (expected faults whose true onset preceded calibration) and
        ``first_answers``: of the expected faults with a true onset (``total``), those whose
        earliest answer (:func:`first_answers`) was right (``correct``) and right within
        :data:`FIRST_ANSWER_REVS` of the onset (``correct_in_time``); the same for each case's
        first expected fault alone (``cases``, ``cases_in_time``; the later ones are its
        consequences, such as the contacts of a large mass loss); the provisional events
        published (``provisional``), how many the decision revised (``revised``) and those of
        episodes whose final event matched no expected fault (``false_alarms``).
    """
    classes = [t.name for t in FaultType if t != FaultType.TRIP]
    cols = [*classes, MISSED, "NO_TRUTH"]
    confusion = {r: dict.fromkeys(cols, 0) for r in [*classes, NONE]}
    per: dict[str, dict[str, list[float]]] = {}
    correct = total = 0
    fa = 0
    sim_s = 0.0
    early = 0
    first = dict.fromkeys(
        (
            "total", "correct", "correct_in_time", "cases", "cases_in_time", "provisional",
            "revised", "false_alarms",
        ),
        0,
    )  # fmt: skip
    for r in results:
        sim_s += r.duration
        first["false_alarms"] += len(r.provisional_false_alarms)
        for e in r.events:
            status, revised = event_status(e["evidence"])
            first["provisional"] += status == PROVISIONAL
            first["revised"] += status == FINAL and revised
        answered = [m for m in r.matches if "first_predicted" in m]
        for k, m in enumerate(sorted(answered, key=lambda m: m["true_onset_sample"])):
            right = m["first_predicted"] == m["expected"]
            in_time = right and m["first_decision_revs"] <= FIRST_ANSWER_REVS
            first["total"] += 1
            first["correct"] += right
            first["correct_in_time"] += in_time
            if k == 0:  # the case's own fault (later ones: its consequences)
                first["cases"] += 1
                first["cases_in_time"] += in_time
        for m in r.matches:
            total += 1
            early += bool(m.get("before_calibration"))
            confusion[m["expected"]][m["predicted"]] += 1
            if m["predicted"] == m["expected"]:
                correct += 1
                d = per.setdefault(m["expected"], {})
                d.setdefault("detection_ms", []).append(m["detection_delay_ms"])
                d.setdefault("detection_revs", []).append(m["detection_delay_revs"])
                d.setdefault("decision_revs", []).append(m["decision_delay_revs"])
                d.setdefault("onset_error_ms", []).append(m["onset_error_ms"])
                d.setdefault("onset_error_supports", []).append(
                    m["onset_error_samples"] / r.finest_support
                )
        for f in r.false_alarms:
            fa += 1
            confusion[NONE][f["predicted"]] += 1
    delays = {}
    for cls, d in per.items():
        delays[cls] = {
            "n": len(d["detection_ms"]),
            "detection_ms_median": float(np.median(d["detection_ms"])),
            "detection_ms_max": float(np.max(d["detection_ms"])),
            "detection_revs_max": float(np.max(d["detection_revs"])),
            "decision_revs_median": float(np.median(d["decision_revs"])),
            "decision_revs_max": float(np.max(d["decision_revs"])),
            "onset_error_ms_median": float(np.median(d["onset_error_ms"])),
            "onset_error_abs_supports_max": float(np.max(np.abs(d["onset_error_supports"]))),
        }
    return {
        "confusion": confusion,
        "delays": delays,
        "false_alarms": fa,
        "simulated_s": sim_s,
        "false_alarms_per_hour": fa / sim_s * 3600.0 if sim_s else 0.0,
        "correct": correct,
        "total": total,
        "before_calibration": early,
        "first_answers": first,
    }
