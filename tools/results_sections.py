"""
The sections of ``docs/results.md``: :class:`Section`, the model and run sections, ``SECTIONS``.

A :class:`Section` is a name, a title, its rough cost, what its numbers back, the commands it
runs and how their output becomes Markdown. This module holds the sections of the model and of
whole runs (``modal``, ``prediction``, ``drain``, ``demo``, ``fault-eval``, ``compare``); the
timing benchmarks are in ``results_benchmarks``. ``SECTIONS`` is every section in the
document's order, ``BY_NAME`` the same by name.
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from results_benchmarks import (
    _deployment_commands,
    _deployment_report,
    _executor_commands,
    _executor_report,
    _msg_commands,
    _msg_report,
    _plant_commands,
    _plant_report,
)
from results_commands import ROOT, Command, Output
from results_markdown import _num, table
from results_parsers import (
    parse_bound,
    parse_compare,
    parse_demo,
    parse_fault_eval,
    parse_modal,
    parse_prediction,
    parse_run,
)

from amb_apps import compare_targets


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


#: revolutions after an episode's onset of the provisional classes scored (issue 19)
PROVISIONAL_REVS = "1.5"


def _fault_commands(work: Path, args) -> list[Command]:
    def evaluate(folder: str, *extra: str) -> Command:
        argv = ["amb-fault-eval", "--scenarios", folder, "--wavelet", FAULT_WAVELETS, *extra]
        return Command(
            [*argv, "--json"],
            ok=(0, 1),
            why="1 = a misclassified case or a false alarm (reported below)",
        )

    return [
        evaluate("config/scenarios/faults"),
        evaluate("config/scenarios/faults", "--provisional", PROVISIONAL_REVS),
        evaluate("config/scenarios/healthy_long", "--provisional", PROVISIONAL_REVS),
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
    early = parse_fault_eval(outs[1].stdout)
    lines += [
        "",
        f"Provisional classes ({PROVISIONAL_REVS} revolutions after each episode's onset, "
        "`--provisional`): the earliest answer, provisional or final, right within "
        "2 revolutions of the true onset, for each case's first fault; the final classes as "
        "above:",
        "",
    ]
    lines += table(
        ["wavelet", "in time", "share", "provisional events", "revised at the decision",
         "provisional false alarms", "final correct"],
        [
            [
                w,
                f"{f['cases_in_time']}/{f['cases']}",
                f"{f['cases_in_time'] / max(f['cases'], 1):.0%}",
                f["provisional"],
                f["revised"],
                f["false_alarms"],
                f"{p['correct']}/{p['total']}",
            ]
            for w, p in early.items()
            for f in [p["first_answers"]]
        ],
    )  # fmt: skip
    quiet = parse_fault_eval(outs[2].stdout)
    first = next(iter(quiet.values()))
    cases = first.get("cases") or []
    runs = ""  # what was run, from the command's own output
    if cases:
        each = first["simulated_s"] / len(cases)
        speeds = ", ".join(f"{c['speed_hz']:g}" for c in cases)
        runs = f": {each:g} s each at {speeds} Hz"
    lines += [
        "",
        f"Long healthy running (`config/scenarios/healthy_long`{runs}; provisional classes at "
        f"{PROVISIONAL_REVS}):",
        "",
    ]
    lines += table(
        ["wavelet", "simulated (s)", "false alarms", "provisional events"],
        [
            [w, f"{p['simulated_s']:.1f}", p["false_alarms"], p["first_answers"]["provisional"]]
            for w, p in quiet.items()
        ],
    )
    return lines


def _compare_commands(work: Path, args) -> list[Command]:
    return [Command(["amb-compare", "--multilevel", "--robustness", "--out", str(work / "run")])]


def _compare_report(outs: list[Output], work: Path) -> list[str]:
    path = work / "run" / "comparison.json"
    doc = parse_compare(path.read_text() if path.is_file() else "")
    lines = [
        "Controllers x scenarios (`amb-compare --multilevel --robustness`; rows and metrics "
        "defined in `amb-compare`'s documentation). Peaks and residuals at the inner sensors, "
        f"forces per bearing axis (limit {_num(doc.get('force_limit'), 'g')} N).",
    ]
    for key, rows in doc["table"].items():
        lines += ["", f"`{key}` ({doc['speeds_hz'].get(key, float('nan')):.2f} Hz):", ""]
        lines += table(
            [
                "row",
                "peak (µm)",
                "revs to 10 %",
                "revs to 10 % (1 x)",
                "revs < 10 % PID",
                "peak 1 x (µm)",
                "residual (µm)",
                "3x / 5x / 7x (µm)",
                "peak force (N)",
                "RMS force (N)",
                "contacts",
                "model radius",
                "peak / limit",
            ],
            [
                [
                    name,
                    _num(m["peak"], ".1f", 1e6),
                    _num(m["revs_to_10"], "d"),
                    _num(m.get("revs_to_10_1x"), "d"),
                    _num(m.get("revs_below_10pct_pid"), "d"),
                    _num(m.get("peak_1x"), ".1f", 1e6),
                    _num(m.get("residual_um"), ".1f"),
                    " / ".join(
                        _num(m.get("harmonics_um", {}).get(h), ".1f") for h in ("3x", "5x", "7x")
                    ),
                    _num(m["peak_force"], ".0f"),
                    _num(m.get("rms_force"), ".1f"),
                    m["contacts"],
                    _num(m.get("model_radius"), ".4f"),
                    _num(m.get("peak_to_limit"), ".2f"),
                ]
                for name, m in rows.items()
            ],
        )
        for name, why in doc.get("limits_unavailable", {}).get(key, {}).items():
            lines += ["", f"No {name} row: {why}."]
    robust = doc.get("robustness")
    if robust:
        cases = list(next(iter(robust.values())))
        lines += ["", "Robustness (first-critical mass loss), peak after the fault (µm):", ""]
        lines += table(
            ["row", *cases],
            [
                [n, *(_num(rows[c]["peak"], ".1f", 1e6) for c in cases)]
                for n, rows in robust.items()
            ],
        )
    lines += compare_targets.markdown(
        compare_targets.checks(doc["table"], robust, doc.get("limits_unavailable")), level=3
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


def _bound_commands(work: Path, args) -> list[Command]:
    return [Command(["amb-bound", "--out", str(work / "run")])]


def _bound_report(outs: list[Output], work: Path) -> list[str]:
    path = work / "run" / "bound.json"
    doc = parse_bound(path.read_text() if path.is_file() else "")
    lines = [
        "The best peak any controller with delay i could give (`amb-bound`: clairvoyant added "
        f"force within {_num(doc['force_limit'], 'g')} N per axis, total control force and "
        "clearances as constraints, replayed noise-free on the simulated rig). Floor: the "
        "largest inner |x| between the fault's revolution start and the first sample a "
        "command can reach, which no force changes.",
        "",
    ]
    rows = []
    for c in doc["cases"]:
        if "unavoidable" in c:
            rows.append([c["scenario"], c["delay"], c["phase"], c["unavoidable"]] + [""] * 6)
            continue
        rows.append(
            [
                c["scenario"],
                c["delay"],
                f"{c['fault_phase']:.3f}{' (own)' if c['phase'] == 'own' else ''}",
                f"{c['acts_after_rev']:.3f}",
                _num(c["peak"], ".1f", 1e6),
                _num(c["replay_peak"], ".1f", 1e6),
                _num(c["floor"], ".1f", 1e6),
                _num(c["pid_peak"], ".1f", 1e6),
                _num(c.get("revs_below_10pct_pid"), "d"),
                _num(c["peak_force"], ".0f"),
            ]
        )
    lines += table(
        [
            "scenario",
            "i",
            "fault at (rev of its period)",
            "force from (rev after fault)",
            "limit (µm)",
            "replayed (µm)",
            "floor (µm)",
            "PID only (µm)",
            "revs below 10 % PID",
            "peak force (N)",
        ],
        rows,
    )
    return lines


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
        "amb_apps.prediction_cli: which sensors are inverted",
        _prediction_commands,
        _prediction_report,
    ),
    Section(
        "drain",
        "amb-run draining a lagging fault monitor",
        "minutes",
        "amb_apps.run_end.DRAIN_TIMEOUT",
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
        "deployment",
        "The node set at 67 Hz x 32: processes, composed, the recorder in the stack",
        "tens of minutes",
        "README (amb-run --composed at the rig's top speed), amb_apps.stack",
        _deployment_commands,
        _deployment_report,
    ),
    Section(
        "fault-eval",
        "Fault monitor over the chapter-5 suite",
        "tens of minutes",
        "the fault monitor's onset, delay and false-alarm figures, its provisional classes",
        _fault_commands,
        _fault_report,
    ),
    Section(
        "bound",
        "The control limit: the best any controller could do",
        "about 20 minutes",
        "amb_plant_sim.control_limit, the limit rows of amb-compare",
        _bound_commands,
        _bound_report,
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
