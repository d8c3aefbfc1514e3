"""
The timing benchmarks of ``docs/results.md``: their commands and their Markdown.

The sections ``msg-arrays`` (``python -m timeit`` on filling a ``float64[]`` message field),
``plant-bench`` (``bench/plant_sim.py`` at one OpenBLAS thread and at ``nproc``) and
``executor`` (``bench/pipeline.py`` with each rclpy executor) and ``deployment``
(``bench/pipeline.py`` at the rig's top speed, each way of grouping the nodes in processes).
``results_sections.SECTIONS`` lists them with the others.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from results_commands import Command, Output
from results_markdown import _num, table
from results_parsers import parse_pipeline_bench, parse_plant_bench, parse_timeit

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


BENCH_CASES = "67:32,11:64"


def _executor_commands(work: Path, args) -> list[Command]:
    argv = [sys.executable, "bench/pipeline.py", "--duration", "4", "--cases", BENCH_CASES]
    return [Command(argv, env={"AMB_EXECUTOR": e}, echo_stdout=True) for e in ("events", "single")]


def _cells(r: dict, columns: tuple[tuple[str, str], ...]) -> list:
    """A row's cells: ``(key, format)`` per column (format "": the value as it is)."""
    return [_num(r[key], fmt) if fmt else r[key] for key, fmt in columns]


def _executor_report(outs: list[Output], work: Path) -> list[str]:
    columns = (
        ("rtf", ".2f"), ("p50_ms", ".2f"), ("p99_ms", ".2f"), ("p99_of_period", ".1%"),
        ("missing", ""), ("late", ""), ("load", ".1f"),
    )  # fmt: skip
    rows = [
        [f"{r['case']} {r['run']}", executor, *_cells(r, columns)]
        for executor, out in zip(("events", "single"), outs, strict=True)
        for r in parse_pipeline_bench(out.stdout)
    ]
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


#: (label, bench/pipeline.py arguments) of the ``deployment`` section, in the order run.
DEPLOYMENTS = (
    ("one process per node (recorder on UDP)", []),
    ("one process per node, recorder on shared memory", ["--shm", "recorder"]),
    ("wavelet_stack, recorder apart", ["--composed", "--apart", "recorder"]),
    ("wavelet_stack with the recorder", ["--composed"]),
    (
        "wavelet_stack with the recorder, monitor apart (nice 5)",
        ["--composed", "--apart", "fault_monitor", "--nice", "fault_monitor=5"],
    ),
)


def _deployment_commands(work: Path, args) -> list[Command]:
    argv = [sys.executable, "bench/pipeline.py", "--cases", "67:32", "--duration", "20",
            "--repeat", "3"]  # fmt: skip
    return [Command(argv + extra, echo_stdout=True) for _, extra in DEPLOYMENTS]


def _deployment_report(outs: list[Output], work: Path) -> list[str]:
    columns = (
        ("rtf", ".2f"), ("controlled", ".1%"), ("p99_of_period", ".0%"),
        ("arrival_p99_ms", "+.1f"), ("missing", ""), ("late", ""), ("pub_max_ms", ".2f"),
        ("write_max_ms", ".2f"), ("load", ".1f"),
    )  # fmt: skip
    rows = [
        [label, r["run"], *_cells(r, columns)]
        for (label, _), out in zip(DEPLOYMENTS, outs, strict=True)
        for r in parse_pipeline_bench(out.stdout)
    ]
    lines = [
        "The four nodes and the recorder at 67 Hz x 32 samples/rev (`bench/pipeline.py`, 20 s "
        "simulated per run, 3 runs and their median per deployment, transient control ACTIVE): "
        "lock-step real-time factor; in `realtime` the share of control periods that ran with "
        "their command, the p99 command latency as a share of the period, the p99 of a "
        "command's arrival minus its period's start (negative: in time), commands missing and "
        "late, the plant's largest publication lag and its longest single measurement write. "
        "`load`: 1-minute load average at the end of each run. The separate recorder runs on "
        "UDP as `amb-run` runs it, once on shared memory (`--shm recorder`).",
        "",
    ]
    return lines + table(
        [
            "deployment",
            "run",
            "lock-step RTF",
            "controlled",
            "p99 / period",
            "arrival p99 (ms)",
            "missing",
            "late",
            "pub max (ms)",
            "write max (ms)",
            "load",
        ],
        rows,
    )
