#!/usr/bin/env python3
"""
Regenerate ``docs/results.md``: the measured numbers that the code's docstrings point to.

The docstrings say what the code does and why; where a reason is a measurement they cite a
section of ``docs/results.md`` (``docs/results.md#<section>``). This script makes each section
by running the project's own commands (console scripts, ``make demo``, the benchmarks in
``bench/``) as subprocesses, parsing what they print or write, and writing the numbers with the
command, the commit, the date, the machine (``nproc``, CPU model) and its load, so that a number
cannot go stale silently: rerun the section. It never imports the application's modules.

::

    make results                                  # every section (long: see --list)
    make results SECTIONS="modal prediction"      # some sections; the others are kept
    python tools/results.py --list                # the sections, their commands and cost
    python tools/results.py --dry-run [SECTION ...]   # the commands, nothing run or written

Run it from the repository with the workspace sourced (``source tools/env.sh``; ``make
results`` does it). Progress goes to stderr. If a command fails (an exit status it does not
allow) or its output cannot be parsed, the script says which, with the command and the end of
its output, writes the sections finished before it, and exits with status 1.

Numbers that no command regenerates cheaply (one-off experiments, the history of a design) are
in ``docs/history.md``, ``docs/controller_notes.md`` and ``docs/fault_monitor_notes.md``.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import platform
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCUMENT = ROOT / "docs" / "results.md"
#: How the code cites a section (the test checks that every cited anchor exists).
CITE = re.compile(r"docs/results\.md#([A-Za-z0-9_-]+)")


class ResultsError(RuntimeError):
    """A command failed or printed something its parser does not recognise."""


# --------------------------------------------------------------------------------------------
# Commands
# --------------------------------------------------------------------------------------------


@dataclass
class Command:
    """One subprocess of a section: argv, extra environment, allowed exit statuses."""

    argv: list[str]
    env: dict[str, str] = field(default_factory=dict)
    ok: tuple[int, ...] = (0,)
    echo_stdout: bool = False  # stream stdout to stderr as progress (human-readable output)
    why: str = ""  # what an allowed non-zero status means

    def shell(self) -> str:
        """The command as one would type it (``python`` for this interpreter)."""
        env = " ".join(f"{k}={shlex.quote(v)}" for k, v in self.env.items())
        argv = ["python" if self.argv[0] == sys.executable else self.argv[0], *self.argv[1:]]
        return (env + " " if env else "") + shlex.join(argv)


@dataclass
class Output:
    """What a command printed, its status and how long it took."""

    command: Command
    stdout: str
    stderr: str
    returncode: int
    wall_s: float


def _pump(stream, sink: list[str], echo: bool) -> None:
    for line in stream:
        sink.append(line)
        if echo:
            print(f"[results]   | {line.rstrip()}", file=sys.stderr, flush=True)
    stream.close()


def run_command(section: str, cmd: Command, work: Path) -> Output:
    """Run ``cmd`` from the repository root; raise :class:`ResultsError` unless it succeeds."""
    exe = cmd.argv[0]
    if shutil.which(exe) is None and not Path(exe).is_file():
        raise ResultsError(
            f"{section}: `{exe}` is not on PATH: run `source tools/env.sh` first (or use "
            "`make results`, which does)"
        )
    env = {**os.environ, **cmd.env}
    print(f"[results] {section}: {cmd.shell()}", file=sys.stderr, flush=True)
    t0 = time.monotonic()
    proc = subprocess.Popen(
        cmd.argv,
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        errors="replace",
    )
    out: list[str] = []
    err: list[str] = []
    threads = [
        threading.Thread(target=_pump, args=(proc.stdout, out, cmd.echo_stdout)),
        threading.Thread(target=_pump, args=(proc.stderr, err, True)),
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    rc = proc.wait()
    wall = time.monotonic() - t0
    result = Output(cmd, "".join(out), "".join(err), rc, wall)
    print(f"[results] {section}: exit {rc} after {wall:.1f} s", file=sys.stderr, flush=True)
    if rc not in cmd.ok:
        tail = "\n".join((result.stdout + result.stderr).splitlines()[-20:])
        raise ResultsError(
            f"{section}: `{cmd.shell()}` exited with status {rc} (allowed: "
            f"{', '.join(map(str, cmd.ok))}); last lines of its output:\n{tail}"
        )
    return result


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
    r"(?P<p99>\S+)\s+(?P<frac>\S+)%\s+(?P<missing>-?\d+)\s+(?P<late>-?\d+)\s+(?P<load>\S+)\s*$",
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
            "missing": int(m["missing"]),
            "late": int(m["late"]),
            "load": float(m["load"]),
        }
        for m in _BENCH_ROW.finditer(text)
    ]
    if not rows:
        raise _fail("executor", "rows '<hz> Hz x <spr> #<run> <rtf> <p50> <p99> <frac>% ...'", text)
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


# --------------------------------------------------------------------------------------------
# Formatting
# --------------------------------------------------------------------------------------------


def _num(v, fmt: str = ".3g", scale: float = 1.0) -> str:
    if v is None:
        return "-"
    if isinstance(v, float) and v != v:
        return "nan"
    return format(v * scale if scale != 1.0 else v, fmt)


def table(head: list[str], rows: list[list], numeric: bool = True) -> list[str]:
    """A Markdown table: first column left-aligned, the others right-aligned if ``numeric``."""
    rule = "|---|" + ("---:|" if numeric else "---|") * (len(head) - 1)
    out = ["| " + " | ".join(head) + " |", rule]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return out


# --------------------------------------------------------------------------------------------
# Sections
# --------------------------------------------------------------------------------------------


@dataclass
class Section:
    """One section of ``docs/results.md``: its commands and how its output becomes Markdown."""

    name: str
    title: str
    cost: str  # rough: "seconds", "minutes", "tens of minutes"
    regenerates: str
    commands: Callable[[Path, argparse.Namespace], list[Command]]
    report: Callable[[list[Output], Path], list[str]]


def _modal_commands(work: Path, args) -> list[Command]:
    return [Command(["amb-modal"])]


def _modal_report(outs: list[Output], work: Path) -> list[str]:
    r = parse_modal(outs[0].stdout)
    roles = ("first", "second", "third", "fourth")
    lines = ["Critical speeds (running speed = a forward-whirl natural frequency), Hz:", ""]
    lines += table(
        [f"{roles[i] if i < len(roles) else i + 1}" for i in range(len(r["critical_speeds_hz"]))],
        [[f"{c:.3f}" for c in r["critical_speeds_hz"]]],
    )
    lines += ["", f"Modes of the PID closed loop at {_num(r['speed_hz'], 'g')} Hz:", ""]
    lines += table(
        ["mode", "frequency (Hz)", "damping ratio", "whirl"],
        [
            [m["mode"], f"{m['frequency_hz']:.3f}", f"{m['damping']:.4f}", m["whirl"]]
            for m in r["modes"]
        ],
    )
    if r["sensitivity"]:
        lines += ["", "Sensitivity peaks (ISO 14839-3):", ""]
        lines += table(
            ["axis", "peak", "dB", "at (Hz)", "zone"],
            [
                [
                    s["axis"],
                    f"{s['peak']:.3f}",
                    f"{s['peak_db']:.2f}",
                    f"{s['frequency_hz']:.1f}",
                    s["zone"],
                ]
                for s in r["sensitivity"]
            ],
        )
    return lines


_MSG_SETUP = (
    "import numpy as np; from array import array; from amb_msgs.msg import ControlCommand; "
    "m = ControlCommand(); x = np.random.default_rng(0).standard_normal(1000)"
)
_MSG_CASES = (
    (
        "array('d', x.tobytes()) (amb_tools.conversions.to_float_array)",
        'm.force = array("d", x.tobytes())',
    ),
    ("the numpy array itself (element by element)", "m.force = x"),
)


def _msg_commands(work: Path, args) -> list[Command]:
    return [
        Command([sys.executable, "-m", "timeit", "-s", _MSG_SETUP, stmt]) for _, stmt in _MSG_CASES
    ]


def _msg_report(outs: list[Output], work: Path) -> list[str]:
    times = [parse_timeit(o.stdout) for o in outs]
    lines = [
        "Filling the `float64[]` field `ControlCommand.force` with 1000 values (best of "
        "`timeit`'s repeats):",
        "",
    ]
    lines += table(
        ["assigned value", "time per 1000 values (µs)", "ratio to the first"],
        [
            [label, f"{t * 1e6:.2f}", f"{t / times[0]:.0f}"]
            for (label, _), t in zip(_MSG_CASES, times, strict=True)
        ],
    )
    return lines


def _plant_commands(work: Path, args) -> list[Command]:
    argv = [sys.executable, "bench/plant_sim.py", "--seconds", "2", "--repeats", "3"]
    return [
        Command(argv, env={"OPENBLAS_NUM_THREADS": "1"}, echo_stdout=True),
        Command(argv, env={"OPENBLAS_NUM_THREADS": str(os.cpu_count() or 1)}, echo_stdout=True),
    ]


def _plant_report(outs: list[Output], work: Path) -> list[str]:
    one, many = (parse_plant_bench(o.stdout) for o in outs)
    rows = []
    for key, a in one["rows"].items():
        hz, spr, case = key
        b = many["rows"][key]
        rows.append(
            [
                f"{hz} Hz, {spr} samples/rev, {case}",
                f"{a['x_real_time']:.1f}",
                f"{1e3 / (a['x_real_time'] * hz):.2f}",
                f"{a['stepwise_pct']:.1f}",
                f"{b['x_real_time']:.1f}",
                f"{a['x_real_time'] / b['x_real_time']:.2f}",
            ]
        )
    lines = [
        "Plant core, simulated seconds per wall second (median of 3 runs of 2 s simulated; "
        "`stepwise`: share of samples integrated step by step, as contacts are):",
        "",
    ]
    lines += table(
        [
            "case",
            f"x real time, {one['threads']} thread",
            "wall ms per revolution",
            "stepwise %",
            f"x real time, {many['threads']} threads",
            f"ratio {one['threads']} / {many['threads']} threads",
        ],
        rows,
    )
    return lines


def _prediction_commands(work: Path, args) -> list[Command]:
    return [
        Command(["amb-prediction", "--out", str(work / "prediction_all"), "--json"]),
        Command(
            [
                "amb-prediction",
                "--out",
                str(work / "prediction_inner"),
                "--json",
                "--inverse-sensors",
                "inner",
            ]
        ),
    ]


def _prediction_report(outs: list[Output], work: Path) -> list[str]:
    lines = [
        "Steady-state prediction on the 22 Hz, 200 N step synchronous force (PID only): settling "
        "time after the step, s (worst x sensor), and predicted / measured final 1 x amplitude "
        "per x sensor.",
    ]
    for label, out in zip(("all 8 sensors (default)", "inner sensors"), outs, strict=True):
        doc = parse_prediction(out.stdout)
        sensors = sorted(next(iter(doc.values()))["sensors"])
        lines += ["", f"Inverted model: {label}.", ""]
        lines += table(
            [
                "wavelet",
                "measured settling (s)",
                "predicted settling (s)",
                *[f"ratio {s}" for s in sensors],
            ],
            [
                [
                    w,
                    _num(s["measured_settling_s"]),
                    _num(s["predicted_settling_s"]),
                    *[_num(s["sensors"][n]["amplitude_ratio"]) for n in sensors],
                ]
                for w, s in doc.items()
            ],
        )
    return lines


DRAIN_SCENARIO = "mass_loss_first_critical.yaml"


def _drain_commands(work: Path, args) -> list[Command]:
    return [
        Command(
            [
                "amb-run",
                "--scenario",
                DRAIN_SCENARIO,
                "--controller",
                "none",
                "--nice",
                "fault_monitor=19",
                "--out",
                str(work / "run"),
            ],
            echo_stdout=True,
        )
    ]


def _samples_per_rev(scenario: str) -> int | None:
    pattern = re.compile(r"^\s*samples_per_rev:\s*(\d+)", re.M)
    for path in (ROOT / "config" / "scenarios" / scenario, ROOT / "config" / "amb_params.yaml"):
        m = pattern.search(path.read_text()) if path.is_file() else None
        if m:
            return int(m[1])
    return None


def _drain_report(outs: list[Output], work: Path) -> list[str]:
    log = work / "run" / "logs" / "plant_sim.log"
    r = parse_run(outs[0].stdout, log.read_text() if log.is_file() else "")
    spr = _samples_per_rev(DRAIN_SCENARIO)
    rows = []
    for name, v in r["at_plant_end"].items():
        behind = None if v is None else r["last_sample"] - v
        revs = "-" if behind is None or not spr else f"{behind / spr:.1f}"
        rows.append([name, _num(v, "d"), _num(behind, "d"), revs])
    drained = (
        f"drained in {r['drained_s']:.1f} s"
        if r["drained_s"] is not None
        else f"NOT drained within the {r['drain_timeout_s']:g} s timeout"
    )
    lines = [
        f"`{DRAIN_SCENARIO}`, PID only, fault monitor at nice 19 (the others at amb-run's "
        f"defaults): plant {r['sim_s']:.3f} s simulated in {r['plant_wall_s']:.1f} s wall "
        f"(real-time factor {r['real_time_factor']:.2f}); at the plant's last sample "
        f"({r['last_sample']}) "
        f"the drained nodes stood at (samples per revolution {spr}):",
        "",
    ]
    lines += table(["node, key", "processed", "samples behind", "revolutions behind"], rows)
    lines += ["", f"Then {drained}; the whole run took {r['wall_s']:.1f} s wall."]
    return lines


#: ``make demo``'s output folder, relative: tools/demo.sh builds paths as ``$PWD/$OUT``.
DEMO_OUT = "out/results/demo"


def _demo_commands(work: Path, args) -> list[Command]:
    return [Command(["make", "demo"], env={"OUT": DEMO_OUT}, echo_stdout=True)]


def _demo_report(outs: list[Output], work: Path) -> list[str]:
    r = parse_demo(outs[0].stdout)
    lines = [
        f"`make demo` took {r['wall_s']} s wall (its own `[demo] done in` line). Key metrics "
        "(`amb-report`'s `comparison.md`):",
        "",
    ]
    if r["fault_time"]:
        lines += [r["fault_time"], ""]
    return lines + r["table"]


FAULT_WAVELETS = "haar,db2,db4"


def _fault_commands(work: Path, args) -> list[Command]:
    return [
        Command(
            [
                "amb-fault-eval",
                "--scenarios",
                "config/scenarios/faults",
                "--wavelet",
                FAULT_WAVELETS,
                "--json",
            ],
            ok=(0, 1),
            why="1 = a misclassified case or a false alarm (reported below)",
        )
    ]


def _fault_report(outs: list[Output], work: Path) -> list[str]:
    parts = parse_fault_eval(outs[0].stdout)
    lines = [
        "Fault monitor over `config/scenarios/faults` (one simulation per scenario, the "
        "monitor once per wavelet):",
        "",
    ]
    lines += table(
        ["wavelet", "correct", "false alarms", "simulated (s)", "false alarms per hour"],
        [
            [
                w,
                f"{p['correct']}/{p['total']}",
                p["false_alarms"],
                f"{p['simulated_s']:.1f}",
                f"{p['false_alarms_per_hour']:.2f}",
            ]
            for w, p in parts.items()
        ],
    )
    for w, p in parts.items():
        lines += ["", f"Delays and onset errors, {w} (correct matches only):", ""]
        lines += table(
            [
                "class",
                "n",
                "detection ms median",
                "detection ms max",
                "detection revs max",
                "decision revs median",
                "decision revs max",
                "onset error ms median",
                "abs onset error max (finest supports)",
            ],
            [
                [
                    cls,
                    d["n"],
                    f"{d['detection_ms_median']:.2f}",
                    f"{d['detection_ms_max']:.2f}",
                    f"{d['detection_revs_max']:.3f}",
                    f"{d.get('decision_revs_median', float('nan')):.2f}",
                    f"{d['decision_revs_max']:.2f}",
                    f"{d['onset_error_ms_median']:.2f}",
                    f"{d['onset_error_abs_supports_max']:.2f}",
                ]
                for cls, d in p["delays"].items()
            ],
        )
    return lines


def _compare_commands(work: Path, args) -> list[Command]:
    return [Command(["amb-compare", "--multilevel", "--out", str(work / "run")])]


def _compare_report(outs: list[Output], work: Path) -> list[str]:
    path = work / "run" / "comparison.json"
    doc = parse_compare(path.read_text() if path.is_file() else "")
    lines = [
        "Controllers x scenarios (`amb-compare --multilevel`; rows and metrics defined in "
        "`amb-compare`'s documentation). Peaks and residuals at the inner sensors, forces per "
        f"bearing axis (limit {_num(doc.get('force_limit'), 'g')} N).",
    ]
    for key, rows in doc["table"].items():
        lines += ["", f"`{key}` ({doc['speeds_hz'].get(key, float('nan')):.2f} Hz):", ""]
        lines += table(
            [
                "row",
                "peak (µm)",
                "revs to 10 %",
                "revs to 10 % (1 x)",
                "peak 1 x (µm)",
                "residual (µm)",
                "3x / 5x / 7x (µm)",
                "peak force (N)",
                "RMS force (N)",
                "contacts",
                "model radius",
            ],
            [
                [
                    name,
                    _num(m["peak"], ".1f", 1e6),
                    _num(m["revs_to_10"], "d"),
                    _num(m.get("revs_to_10_1x"), "d"),
                    _num(m.get("peak_1x"), ".1f", 1e6),
                    _num(m.get("residual_um"), ".1f"),
                    " / ".join(
                        _num(m.get("harmonics_um", {}).get(h), ".1f") for h in ("3x", "5x", "7x")
                    ),
                    _num(m["peak_force"], ".0f"),
                    _num(m.get("rms_force"), ".1f"),
                    m["contacts"],
                    _num(m.get("model_radius"), ".4f"),
                ]
                for name, m in rows.items()
            ],
        )
    lines += ["", "Time for one command (controller step + synthesis + force limit):", ""]
    lines += table(
        ["controller", "median (µs)", "p99 (µs)"],
        [
            [n, f"{t['median_s'] * 1e6:.1f}", f"{t['p99_s'] * 1e6:.1f}"]
            for n, t in doc["timing"].items()
        ],
    )
    return lines


BENCH_CASES = "67:32,11:64"


def _executor_commands(work: Path, args) -> list[Command]:
    argv = [sys.executable, "bench/pipeline.py", "--duration", "4", "--cases", BENCH_CASES]
    return [Command(argv, env={"AMB_EXECUTOR": e}, echo_stdout=True) for e in ("events", "single")]


def _executor_report(outs: list[Output], work: Path) -> list[str]:
    rows = []
    for executor, out in zip(("events", "single"), outs, strict=True):
        for r in parse_pipeline_bench(out.stdout):
            rows.append(
                [
                    f"{r['case']} {r['run']}",
                    executor,
                    f"{r['rtf']:.2f}",
                    _num(r["p50_ms"], ".2f"),
                    _num(r["p99_ms"], ".2f"),
                    _num(r["p99_of_period"], ".1%"),
                    r["missing"],
                    r["late"],
                    f"{r['load']:.1f}",
                ]
            )
    lines = [
        "The four nodes and the recorder over DDS (`bench/pipeline.py`, 4 s simulated per run), "
        "with rclpy's `EventsExecutor` (`AMB_EXECUTOR=events`, the default) and the "
        "`SingleThreadedExecutor` (`single`): lock-step real-time factor, and in realtime mode "
        "the command latency (last sample of a period to the command based on it). `load`: "
        "1-minute load average at the end of each run.",
        "",
    ]
    return lines + table(
        [
            "case / run",
            "executor",
            "lock-step RTF",
            "rt p50 (ms)",
            "rt p99 (ms)",
            "p99 / period",
            "missing",
            "late",
            "load",
        ],
        rows,
    )


SECTIONS = [
    Section(
        "modal",
        "Critical speeds and modes of the rig model",
        "seconds",
        "the critical speeds the controller docstrings and notes name",
        _modal_commands,
        _modal_report,
    ),
    Section(
        "msg-arrays",
        "Filling a float64[] message field",
        "seconds",
        "the cost that makes amb_tools.conversions fill float64[] fields from bytes",
        _msg_commands,
        _msg_report,
    ),
    Section(
        "plant-bench",
        "Plant core speed and OpenBLAS threads",
        "minutes",
        "OPENBLAS_NUM_THREADS=1 (tools/env.sh); the slow contact integration",
        _plant_commands,
        _plant_report,
    ),
    Section(
        "prediction",
        "Steady-state prediction (thesis 7.4.1)",
        "minutes",
        "amb_controller.prediction_cli: which sensors are inverted",
        _prediction_commands,
        _prediction_report,
    ),
    Section(
        "drain",
        "amb-run draining a lagging fault monitor",
        "minutes",
        "amb_tools.run_cli.DRAIN_TIMEOUT",
        _drain_commands,
        _drain_report,
    ),
    Section(
        "demo",
        "make demo",
        "minutes",
        "the README's demo duration and key numbers",
        _demo_commands,
        _demo_report,
    ),
    Section(
        "executor",
        "EventsExecutor against SingleThreadedExecutor",
        "tens of minutes",
        "amb_tools.node_main.make_executor's default",
        _executor_commands,
        _executor_report,
    ),
    Section(
        "fault-eval",
        "Fault monitor over the chapter-5 suite",
        "tens of minutes",
        "the fault monitor's onset, delay and false-alarm figures",
        _fault_commands,
        _fault_report,
    ),
    Section(
        "compare",
        "Controllers x scenarios, multi-level and reconfiguration",
        "tens of minutes",
        "amb_controller.multilevel, amb_controller.supervisor (hold-last or ramp-to-zero), "
        "the Target section of amb-compare",
        _compare_commands,
        _compare_report,
    ),
]
BY_NAME = {s.name: s for s in SECTIONS}


# --------------------------------------------------------------------------------------------
# The document
# --------------------------------------------------------------------------------------------

_BLOCK = re.compile(
    r"<!-- section (?P<name>[A-Za-z0-9_-]+) begin -->\n(?P<body>.*?)<!-- section (?P=name) end -->",
    re.S,
)
_META = re.compile(r"<!-- meta (?P<json>\{.*?\}) -->")


def read_blocks(text: str) -> dict[str, str]:
    """The section blocks of an existing document, by name (text between the markers)."""
    return {m["name"]: m["body"] for m in _BLOCK.finditer(text)}


def block_meta(body: str) -> dict:
    """The metadata line of a section block ({} when the section was never generated)."""
    m = _META.search(body)
    return json.loads(m["json"]) if m else {}


def citations() -> dict[str, list[str]]:
    """Section name -> files that cite ``docs/results.md#<name>`` (code, tools, README, docs)."""
    out: dict[str, list[str]] = {}
    paths = [
        *ROOT.glob("amb_*/**/*.py"),
        *ROOT.glob("tools/*"),
        *ROOT.glob("bench/*.py"),
        ROOT / "README.md",
        *ROOT.glob("docs/*.md"),
        *ROOT.glob("config/*.yaml"),
    ]
    for path in sorted(paths):
        if path == DOCUMENT or not path.is_file() or path.name == "results.py":
            continue
        for name in set(CITE.findall(path.read_text(errors="replace"))):
            out.setdefault(name, []).append(str(path.relative_to(ROOT)))
    return out


def machine() -> dict:
    """nproc, CPU model, OS and Python of this machine."""
    model = platform.processor() or "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "nproc": os.cpu_count(),
        "cpu": model,
        "os": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
    }


def commit() -> str:
    """The commit the numbers were measured on (``+dirty`` with uncommitted code changes)."""

    def git(*a: str) -> str:
        out = subprocess.run(["git", *a], cwd=ROOT, capture_output=True, text=True)
        return out.stdout.strip() if out.returncode == 0 else ""

    head = git("rev-parse", "--short=12", "HEAD") or "unknown"
    dirty = [
        line
        for line in git("status", "--porcelain", "--untracked-files=no").splitlines()
        if not line.endswith("docs/results.md")
    ]
    return head + ("+dirty" if dirty else "")


def render_block(section: Section, meta: dict, body: list[str]) -> str:
    """The text between a section's markers."""
    cmds = "\n".join(meta["commands"])
    load = meta["load_before"], meta["load_after"]
    lines = [
        f"<!-- meta {json.dumps(meta, sort_keys=True)} -->",
        "",
        "```bash",
        cmds,
        "```",
        "",
        f"Measured {meta['date']} on commit `{meta['commit']}`, {meta['machine']['nproc']} CPUs "
        f"({meta['machine']['cpu']}; {meta['machine']['os']}, Python "
        f"{meta['machine']['python']}), 1-minute load average {load[0]:.2f} before and "
        f"{load[1]:.2f} after; {meta['wall_s']:.1f} s wall. Regenerate: `make results "
        f"SECTIONS={section.name}`.",
        "",
        *body,
    ]
    return "\n".join(lines) + "\n"


def placeholder(section: Section, args) -> str:
    """The block of a section never generated: its commands and how to generate it."""
    cmds = "\n".join(c.shell() for c in section.commands(Path("$WORK") / section.name, args))
    return (
        "Not generated yet. Commands:\n\n```bash\n"
        + cmds
        + f"\n```\n\nGenerate: `make results SECTIONS={section.name}`.\n"
    )


def render_document(blocks: dict[str, str]) -> str:
    """The whole document from the section blocks (every section has a block)."""
    rows = []
    for s in SECTIONS:
        meta = block_meta(blocks[s.name])
        when = (
            f"{meta['date']}, `{meta['commit']}`, load {meta['load_before']:.2f}"
            if meta
            else "not generated yet"
        )
        rows.append([f"[{s.name}](#{s.name})", s.regenerates, s.cost, when])
    cited = citations()
    lines = [
        "# Measured results",
        "",
        "<!-- Generated by tools/results.py: edit the script, not this file. -->",
        "This document is generated: `make results` regenerates every section, "
        '`make results SECTIONS="modal prediction"` (or `python tools/results.py modal '
        "prediction` after `source tools/env.sh`) only those and keeps the others as they "
        "are. Each section names its commands and the commit, date, machine and load it was "
        "measured with; timings depend on the machine and on what else runs on it. The code's "
        "docstrings cite these sections (`docs/results.md#<section>`) instead of quoting "
        "numbers. Measurements that no command regenerates cheaply are in `docs/history.md`, "
        "`docs/controller_notes.md` and `docs/fault_monitor_notes.md`.",
        "",
        *table(["section", "regenerates", "cost (rough)", "generated"], rows, numeric=False),
    ]
    for s in SECTIONS:
        lines += [
            "",
            f'<a id="{s.name}"></a>',
            "",
            f"## {s.name}: {s.title}",
            "",
            f"<!-- section {s.name} begin -->",
            blocks[s.name].rstrip("\n"),
            f"<!-- section {s.name} end -->",
        ]
        if cited.get(s.name):
            lines += ["", "Cited by: " + ", ".join(f"`{c}`" for c in cited[s.name]) + "."]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------------
# Main
# --------------------------------------------------------------------------------------------


def build_parser() -> argparse.ArgumentParser:
    """The command line of this script."""
    ap = argparse.ArgumentParser(
        prog="tools/results.py",
        description="Regenerate docs/results.md by running the project's commands.",
    )
    ap.add_argument(
        "sections",
        nargs="*",
        metavar="SECTION",
        help=f"sections to regenerate (default: all): {', '.join(BY_NAME)}",
    )
    ap.add_argument("--list", action="store_true", help="list the sections and exit")
    ap.add_argument(
        "--dry-run", action="store_true", help="print the commands; run and write nothing"
    )
    ap.add_argument("--out", type=Path, default=DOCUMENT, help="document (default docs/results.md)")
    ap.add_argument("--keep", type=Path, default=None, help="keep the commands' outputs in DIR")
    return ap


def _selected(args) -> list[Section]:
    names = [n for item in args.sections for n in item.replace(",", " ").split()]
    unknown = [n for n in names if n not in BY_NAME]
    if unknown:
        raise SystemExit(
            f"tools/results.py: unknown section(s) {', '.join(unknown)}; known: "
            f"{', '.join(BY_NAME)}"
        )
    return [BY_NAME[n] for n in names] if names else list(SECTIONS)


def run_section(section: Section, work: Path, args) -> str:
    """Run one section's commands; return its block (raises ResultsError on failure)."""
    before = os.getloadavg()[0]
    date = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    t0 = time.monotonic()
    section_work = work / section.name
    section_work.mkdir(parents=True, exist_ok=True)
    cmds = section.commands(section_work, args)
    outs = [run_command(section.name, c, section_work) for c in cmds]
    body = section.report(outs, section_work)
    meta = {
        "date": date,
        "commit": commit(),
        "machine": machine(),
        "load_before": round(before, 2),
        "load_after": round(os.getloadavg()[0], 2),
        "wall_s": round(time.monotonic() - t0, 1),
        "commands": [c.shell() for c in cmds],
    }
    return render_block(section, meta, body)


def main(argv: list[str] | None = None) -> int:
    """Run the selected sections and rewrite the document; 0 on success, 1 on a failure."""
    args = build_parser().parse_args(argv)
    chosen = _selected(args)
    if args.list:
        for s in SECTIONS:
            cmds = "; ".join(c.shell() for c in s.commands(Path("$WORK") / s.name, args))
            print(f"{s.name:12s} {s.cost:17s} {s.title}\n{'':30s}{cmds}")
        return 0
    if args.dry_run:
        for s in chosen:
            for c in s.commands(Path("$WORK") / s.name, args):
                print(f"{s.name}: {c.shell()}" + (f"   # {c.why}" if c.why else ""))
        return 0
    existing = read_blocks(args.out.read_text()) if args.out.is_file() else {}
    work = args.keep or Path(tempfile.mkdtemp(prefix="amb-results-"))
    work.mkdir(parents=True, exist_ok=True)
    blocks = dict(existing)
    done: list[str] = []
    status = 0
    try:
        for i, s in enumerate(chosen, 1):
            print(f"[results] section {i}/{len(chosen)}: {s.name} ({s.cost})", file=sys.stderr)
            try:
                blocks[s.name] = run_section(s, work, args)
                done.append(s.name)
            except ResultsError as exc:
                print(f"[results] FAILED: {exc}", file=sys.stderr)
                status = 1
                break
    finally:
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)
    for s in SECTIONS:  # never generated: its current commands
        if not block_meta(blocks.get(s.name, "")):
            blocks[s.name] = placeholder(s, args)
    args.out.write_text(render_document(blocks))
    print(
        f"[results] wrote {args.out} ({', '.join(done) or 'no section regenerated'})",
        file=sys.stderr,
    )
    return status


if __name__ == "__main__":
    raise SystemExit(main())
