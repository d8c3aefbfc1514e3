"""
The parsers of ``tools/results.py``: what each command prints or writes, read into numbers.

Each ``parse_*`` function takes the text one of the project's commands printed (or the file it
wrote) and returns what the sections of ``docs/results.md`` report; output a parser does not
recognise raises :class:`ResultsError` with the section, what was expected and the start of the
text. They are pure functions of that text, tested on captured samples.
"""

from __future__ import annotations

import json
import re


class ResultsError(RuntimeError):
    """A command failed or printed something its parser does not recognise."""


def _fail(section: str, what: str, text: str) -> ResultsError:
    snippet = "\n".join(text.strip().splitlines()[:12]) or "(nothing)"
    return ResultsError(f"{section}: cannot parse the output: expected {what}; got:\n{snippet}")


# --------------------------------------------------------------------------------------------
# Parsers (pure functions of the text a command prints or writes; tested on captured samples)
# --------------------------------------------------------------------------------------------

_MODAL_CRIT = re.compile(r"^critical speeds \(Hz\): (?P<list>[\d., ]+)$", re.M)
_MODAL_MODE = re.compile(
    r"^\s+mode\s+(?P<k>\d+):\s+(?P<f>[\d.]+) Hz\s+damping (?P<z>[\d.]+)\s+(?P<whirl>\S+)$", re.M
)
_MODAL_SPEED = re.compile(r"^speed (?P<hz>[\d.]+) Hz$", re.M)
_MODAL_SENS = re.compile(
    r"^sensitivity (?P<axis>\S+): peak (?P<peak>[\d.]+) \((?P<db>[-\d.]+) dB\) at "
    r"(?P<hz>[\d.]+) Hz, ISO 14839-3 zone (?P<zone>\S+)$",
    re.M,
)


def parse_modal(text: str) -> dict:
    """Parse ``amb-modal``'s text report (one speed): critical speeds, modes, sensitivity."""
    crit = _MODAL_CRIT.search(text)
    if crit is None:
        raise _fail("modal", "a line 'critical speeds (Hz): f1, f2, ...'", text)
    speeds = [float(v) for v in crit["list"].split(",")]
    modes = [
        {
            "mode": int(m["k"]),
            "frequency_hz": float(m["f"]),
            "damping": float(m["z"]),
            "whirl": m["whirl"],
        }
        for m in _MODAL_MODE.finditer(text)
    ]
    if not modes:
        raise _fail("modal", "lines 'mode k: f Hz  damping z  whirl'", text)
    speed = _MODAL_SPEED.search(text)
    sens = [
        {
            "axis": m["axis"],
            "peak": float(m["peak"]),
            "peak_db": float(m["db"]),
            "frequency_hz": float(m["hz"]),
            "zone": m["zone"],
        }
        for m in _MODAL_SENS.finditer(text)
    ]
    return {
        "critical_speeds_hz": speeds,
        "speed_hz": float(speed["hz"]) if speed else None,
        "modes": modes,
        "sensitivity": sens,
    }


_TIMEIT = re.compile(
    r"^(?P<loops>\d+) loops?, best of (?P<best>\d+): (?P<t>[\d.]+) (?P<unit>nsec|usec|msec|sec) "
    r"per loop$",
    re.M,
)
_UNITS = {"nsec": 1e-9, "usec": 1e-6, "msec": 1e-3, "sec": 1.0}


def parse_timeit(text: str) -> float:
    """Parse ``python -m timeit``'s line; return the best time per loop in seconds."""
    m = _TIMEIT.search(text)
    if m is None:
        raise _fail("msg-arrays", "'N loops, best of R: T usec per loop'", text)
    return float(m["t"]) * _UNITS[m["unit"]]


def parse_prediction(text: str) -> dict:
    """Parse ``amb-prediction --json``: per wavelet, settling times and per-sensor results."""
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise _fail("prediction", f"JSON ({exc})", text) from exc
    if not isinstance(doc, dict) or not doc:
        raise _fail("prediction", "a JSON object keyed by wavelet", text)
    for wavelet, s in doc.items():
        keys = {"sensors", "measured_settling_s", "predicted_settling_s"}
        if not isinstance(s, dict) or not keys <= s.keys():
            raise _fail("prediction", f"{wavelet}: keys {sorted(keys)}", text)
        for name, v in s["sensors"].items():
            if "amplitude_ratio" not in v:
                raise _fail("prediction", f"{wavelet} {name}: 'amplitude_ratio'", text)
    return doc


_PLANT_HEAD = re.compile(r"OPENBLAS_NUM_THREADS=(?P<threads>\S+)")
_PLANT_ROW = re.compile(
    r"^(?P<hz>\d+) Hz, (?P<spr>\d+) samples/rev, (?P<case>no contact|contact)\s+"
    r"(?P<rtf>[\d.]+)\s+(?P<build>[\d.]+)\s+(?P<stepwise>[\d.]+)%\s+(?P<contact>\d+)\s*$",
    re.M,
)


def parse_plant_bench(text: str) -> dict:
    """Parse ``bench/plant_sim.py``: OpenBLAS threads and the x-real-time row of each case."""
    head = _PLANT_HEAD.search(text)
    rows = {
        (int(m["hz"]), int(m["spr"]), m["case"]): {
            "x_real_time": float(m["rtf"]),
            "build_s": float(m["build"]),
            "stepwise_pct": float(m["stepwise"]),
            "contact_samples": int(m["contact"]),
        }
        for m in _PLANT_ROW.finditer(text)
    }
    if head is None or len(rows) != 4:
        raise _fail("plant-bench", "the header with OPENBLAS_NUM_THREADS= and 4 case rows", text)
    return {"threads": head["threads"], "rows": rows}


_RUN_DONE = re.compile(r"^\[amb-run\] plant done at sample (?P<last>\d+); (?P<shown>.*)$", re.M)
_RUN_DRAINED = re.compile(r"^\[amb-run\] drained in (?P<s>[\d.]+) s:", re.M)
_RUN_TIMEOUT = re.compile(r"^\[amb-run\] drain timeout \((?P<s>[\d.]+) s", re.M)
_RUN_WALL = re.compile(r"^\[amb-run\] done in (?P<s>[\d.]+) s wall", re.M)
_RUN_NODE = re.compile(r"(?P<node>[a-z_]+) (?P<key>[a-z_]+) (?P<v>-|\d+)")
_PLANT_COMPLETE = re.compile(
    r"complete at t = (?P<t>[\d.]+) s \((?P<n>\d+) samples\) in (?P<wall>[\d.]+) s wall, "
    r"real-time factor (?P<rtf>[\d.]+)"
    r"(?:; command latency p50 (?P<p50>[\d.]+) ms, p99 (?P<p99>[\d.]+) ms)?"
)


def parse_run(stdout: str, plant_log: str) -> dict:
    """Parse ``amb-run``'s drain lines and the plant's completion line (its log)."""
    done = _RUN_DONE.search(stdout)
    wall = _RUN_WALL.search(stdout)
    complete = _PLANT_COMPLETE.search(plant_log)
    if done is None or wall is None:
        raise _fail(
            "drain", "'[amb-run] plant done at sample N; ...' and '... done in S s'", stdout
        )
    if complete is None:
        raise _fail("drain", "the plant's 'complete at t = ... real-time factor R' line", plant_log)
    drained = _RUN_DRAINED.search(stdout)
    timeout = _RUN_TIMEOUT.search(stdout)
    at_end = {
        f"{m['node']} {m['key']}": None if m["v"] == "-" else int(m["v"])
        for m in _RUN_NODE.finditer(done["shown"])
    }
    return {
        "last_sample": int(done["last"]),
        "at_plant_end": at_end,
        "drained_s": float(drained["s"]) if drained else None,
        "drain_timeout_s": float(timeout["s"]) if timeout else None,
        "wall_s": float(wall["s"]),
        "sim_s": float(complete["t"]),
        "plant_wall_s": float(complete["wall"]),
        "real_time_factor": float(complete["rtf"]),
    }


_DEMO_DONE = re.compile(r"^\[demo\] done in (?P<s>\d+) s$", re.M)
_DEMO_TABLE = re.compile(r"^# Key metrics side by side$", re.M)


def parse_demo(text: str) -> dict:
    """Parse ``make demo``: its wall time and the key-metrics table of ``comparison.md``."""
    done = _DEMO_DONE.search(text)
    head = _DEMO_TABLE.search(text)
    if done is None or head is None:
        raise _fail("demo", "'# Key metrics side by side' and '[demo] done in N s'", text)
    rest = text[head.end() :].splitlines()
    table = [line for line in rest if line.startswith("|")]
    fault = next((line for line in rest if line.startswith("Fault time per bag")), "")
    if len(table) < 3:
        raise _fail("demo", "a Markdown table after '# Key metrics side by side'", text)
    return {"wall_s": int(done["s"]), "table": table, "fault_time": fault}


def parse_fault_eval(text: str) -> dict:
    """Parse ``amb-fault-eval --json`` (one or several wavelets): a summary per wavelet."""
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise _fail("fault-eval", f"JSON ({exc})", text) from exc
    parts = doc.get("wavelets", None) if isinstance(doc, dict) else None
    if parts is None and isinstance(doc, dict):
        cases = doc.get("cases") or [{}]
        parts = {cases[0].get("wavelet", "default"): doc}
    keys = {"correct", "total", "false_alarms", "false_alarms_per_hour", "simulated_s", "delays"}
    if not parts or any(not keys <= set(p) for p in parts.values()):
        raise _fail("fault-eval", f"per wavelet the keys {sorted(keys)}", text)
    return parts


_BENCH_ROW = re.compile(
    r"^\s*(?P<hz>[\d.]+) Hz x (?P<spr>\d+) (?P<run>#\d+|median)\s+(?P<rtf>\S+)\s+(?P<p50>\S+)\s+"
    r"(?P<p99>\S+)\s+(?P<frac>\S+)%\s+(?P<controlled>\S+)%\s+(?P<arr99>\S+)\s+"
    r"(?P<missing>-?\d+)\s+(?P<late>-?\d+)\s+(?P<partial>-?\d+)\s+(?P<commanded>\S+)%\s+"
    r"(?P<pub_max>\S+)\s+(?P<write_max>\S+)\s+(?P<load>\S+)"
    r"(?:\s+(?P<hog_on>[\d.]+)-(?P<hog_off>\S+)\s+(?P<before>\S+)%\s+(?P<during>\S+)%\s+"
    r"(?P<during_samples>\S+)%\s+(?P<after>\S+)%\s+(?P<recover>\S+)\s+(?P<lost>-?\d+))?\s*$",
    re.M,
)


def parse_pipeline_bench(text: str) -> list[dict]:
    """Parse ``bench/pipeline.py``'s table: one dict per printed row."""
    rows = [
        {
            "case": f"{m['hz']} Hz x {m['spr']}",
            "run": m["run"],
            "rtf": float(m["rtf"]),
            "p50_ms": float(m["p50"]),
            "p99_ms": float(m["p99"]),
            "p99_of_period": float(m["frac"]) / 100,
            "controlled": float(m["controlled"]) / 100,
            "arrival_p99_ms": float(m["arr99"]),
            "missing": int(m["missing"]),
            "late": int(m["late"]),
            "partial": int(m["partial"]),
            "samples_controlled": float(m["commanded"]) / 100,
            "pub_max_ms": float(m["pub_max"]),
            "write_max_ms": float(m["write_max"]),
            "load": float(m["load"]),
            **(
                {
                    "hog_s": (float(m["hog_on"]), float(m["hog_off"])),
                    **{
                        k: float(m[k]) / 100
                        for k in ("before", "during", "during_samples", "after")
                    },
                    "recover_periods": float(m["recover"]),
                    "lost": int(m["lost"]),
                }
                if m["hog_on"]
                else {}
            ),
        }
        for m in _BENCH_ROW.finditer(text)
    ]
    if not rows:
        raise _fail("pipeline", "rows '<hz> Hz x <spr> #<run> <rtf> <p50> <p99> <frac>% ...'", text)
    return rows


def parse_compare(text: str) -> dict:
    """Parse ``amb-compare``'s ``comparison.json``: the table, speeds, timing."""
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise _fail("compare", f"JSON ({exc})", text) from exc
    if not isinstance(doc, dict) or not {"table", "speeds_hz", "timing"} <= doc.keys():
        raise _fail("compare", "comparison.json with 'table', 'speeds_hz' and 'timing'", text)
    for key, rows in doc["table"].items():
        for name, m in rows.items():
            if not {"peak", "revs_to_10", "peak_force", "contacts"} <= m.keys():
                raise _fail(
                    "compare", f"{key} {name}: peak, revs_to_10, peak_force, contacts", text
                )
    return doc


def parse_bound(text: str) -> dict:
    """Parse ``amb-bound``'s ``bound.json``: the cases (limit, floor, PID, settling)."""
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise _fail("bound", f"JSON ({exc})", text) from exc
    if not isinstance(doc, dict) or not {"cases", "force_limit"} <= doc.keys():
        raise _fail("bound", "bound.json with 'cases' and 'force_limit'", text)
    for case in doc["cases"]:
        if "unavoidable" not in case and not {"peak", "floor", "pid_peak"} <= case.keys():
            raise _fail("bound", "every case with peak, floor and pid_peak", text)
    return doc
