"""
Benchmark: the four-node loop over DDS (amb-run).

Lock-step real-time factor and the command latency in realtime mode.

For each case (running speed, samples per revolution): a wavelet model from the FE route
(``amb-sim --model fe``), then
1. lock-step: ``amb-run`` with plant_sim, wavelet_filterbank, fault_monitor,
   wavelet_controller (transient, ACTIVE) and the recorder; the real-time factor is simulated
   time over wall time from the first sample to the last (plant_sim's own measurement);
2. realtime: the same nodes with ``plant_sim.mode:=realtime``; plant_sim measures, for each
   command, the wall time from the last sample of the period it is based on to its arrival
   (median, p99, as a fraction of the control period), the fraction of the periods that ran
   with a command and the p99 of each command's arrival minus its period's start (negative: in
   time); ``partial``: late commands the plant applied to the rest of their period
   (``partial_commands``), the share of the samples that ran with their command, and the
   plant's largest sample publication lag (``pub max``: its own stall, apart from the nodes')
   and its longest single measurement write (``write max``: held by a reader's shared-memory
   port, ``amb_tools.lossless``, or the plant descheduled in it).
3. with ``--hog START:SECONDS``: during each realtime run a CPU hog (``python -c 'while True:
   pass'``, one core busy) starts START wall s after ``amb-run`` is launched (its start-up
   takes a few seconds: the window actually hit is printed in run time) and runs SECONDS;
   from the bag's ``Measurement.status`` (``STATUS_COMMAND_MISSING``) the fraction of periods
   controlled (every sample with its command) before, during and after the hog (from 2 periods
   after it), the share of the samples during it that ran with their command, how many periods
   after the hog the last uncontrolled one came, and the samples missing from the bag.
4. per run and mode, the CPU of each node other than the plant (``AMB_CPU_LOG``, between the
   plant's first and last sample) per sample the filterbank processed (two per coefficient
   message in the bag: a node set that drops samples to catch up does less than one sample's
   work per plant sample), their sum, and the budget of issue 17: one core, ``1e6 / fs`` us
   per sample (the other core is the bridge's and the operating system's). The transport's
   CPU is inside each node's (Fast DDS's threads run in the node's process).
5. per realtime run and process, what can hold a loop up without CPU of its own: its longest
   garbage collection and the largest run-queue wait of its main thread within 0.1 s
   (``AMB_CPU_LOG``; beside ``pub max``, the plant's largest publication lag).
Each case is run ``--repeat`` times (the model is made once); every run is printed with the
plant's command counts (``missing``: no command by the period's start; ``late``: arrived after)
and the machine's 1-minute load average at its end, then the median over the runs. Numbers
depend on whatever else the machine is doing: read them as ratios to the target, and compare
runs made under the same load.

    python bench/pipeline.py [--duration 8] [--cases 11:64,67:32] [--repeat 3]
        [--composed [--apart fault_monitor]] [--nice NODE=N] [--rt-priority PROCESS=P]
        [--udp PROCESS] [--shm PROCESS] [--hog START:SECONDS]
        [--set NODE.PARAM:=VALUE ...] [--keep DIR]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
COUNTS = re.compile(
    r"commands: applied (?P<applied>\d+), missing (?P<missing>\d+), late (?P<late>\d+)"
)
COMPLETE = re.compile(
    r"in (?P<wall>[\d.]+) s wall, real-time factor (?P<rtf>[\d.]+)"
    r"(?:; command latency p50 (?P<p50>[\d.]+) ms, p99 (?P<p99>[\d.]+) ms \((?P<frac>[\d.]+)%)?"
)
PARTIAL = re.compile(r"partial (?P<partial>\d+)")
SAMPLES = re.compile(r"samples controlled (?P<samples>[\d.]+)%")
PUBLICATION = re.compile(r"sample publication lag p99 [\d.]+ ms, max (?P<pub_max>[\d.]+) ms")
WRITE = re.compile(r"longest measurement write (?P<write_max>[\d.]+) ms")
CONTROL = re.compile(
    r"periods controlled (?P<controlled>[\d.]+)%"
    r"(?:, command arrival - period start p50 (?P<arr50>[-+\d.]+) ms, p99 (?P<arr99>[-+\d.]+) ms)?"
)


def run_checked(cmd: list[str], env: dict | None = None) -> subprocess.CompletedProcess:
    """Run ``cmd`` in the project's root; exit with its output if it fails."""
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, env=env)
    if out.returncode != 0:
        raise SystemExit(f"failed: {' '.join(cmd)}\n{out.stdout}\n{out.stderr}")
    return out


def prepare(hz: float, spr: int, duration: float, work: Path) -> tuple[Path, Path]:
    """Write the case's scenario and its FE wavelet model; return both paths."""
    scenario = work / f"bench_{hz:g}hz.yaml"
    scenario.write_text(
        yaml.safe_dump(
            {
                "name": f"bench_{hz:g}hz",
                "speed": {"hz": hz},
                "duration": duration,
                "samples_per_rev": spr,
                "measurement_noise": 2.0e-7,
                "events": [{"kind": "unbalance", "time": 0.0, "disk": "D1", "me": 1.0e-3}],
            }
        )
    )
    model_dir = work / f"model_{hz:g}"
    run_checked([sys.executable, "-m", "amb_apps.sim_cli", "--scenario", str(scenario),
          "--controller", "transient", "--model", "fe", "--duration", "0.5", "--no-bag",
          "--out", str(model_dir)])  # fmt: skip
    return scenario, model_dir / "model.npz"


class Hog:
    """One core kept busy from ``start`` s after :meth:`arm` for ``seconds`` (a thread waits).

    ``window``: the monotonic (on, off) times the hog actually ran, once it has.
    """

    def __init__(self, start: float, seconds: float) -> None:
        self.start, self.seconds = start, seconds
        self.window: tuple[float, float] | None = None
        self._cancel = threading.Event()
        self._thread: threading.Thread | None = None

    def arm(self) -> None:
        """Start the countdown (call when the run is launched)."""
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        if self._cancel.wait(self.start):
            return
        proc = subprocess.Popen([sys.executable, "-c", "while True: pass"])
        on = time.monotonic()
        self._cancel.wait(self.seconds)
        proc.kill()
        proc.wait()
        self.window = (on, time.monotonic())

    def disarm(self) -> None:
        """Stop the hog (if still running) and wait for its thread."""
        self._cancel.set()
        if self._thread is not None:
            self._thread.join()


def cpu_in_window(usage: dict, t0: float, t1: float) -> float:
    """CPU s a node used between monotonic times ``t0`` and ``t1`` (timeline interpolated)."""
    timeline = np.asarray(usage["timeline"], dtype=float).reshape(-1, 2)
    if timeline.shape[0] < 2:
        return float("nan")
    t, cpu = timeline[:, 0], timeline[:, 1]
    return float(np.interp(t1, t, cpu) - np.interp(t0, t, cpu))


def processed_samples(bag: Path) -> int:
    """Samples the filterbank processed in a run: two per coefficient message in its bag.

    Every odd sample completes a level-1 coefficient; 0 without a bag.
    """
    if not bag.exists():
        return 0
    from amb_common import topics
    from amb_tools.bag_read import read_bag

    data = read_bag(bag)
    return 2 * data.counts.get(data.topic(topics.COEFFICIENTS), 0)


def node_cpu(cpu_log: Path, wall: float) -> dict[str, float]:
    """CPU s of each node of a run between the plant's first and last sample.

    ``cpu_log``: the run's ``AMB_CPU_LOG`` folder; ``wall``: the plant's run wall s (the
    window's length when its CPU log has no ``run_window``).
    """
    plant = json.loads((cpu_log / "plant_sim.cpu.json").read_text())
    # the plant's own first and last sample (its shutdown comes seconds later: acks, report)
    window = tuple(
        plant.get("run_window") or (plant["end_monotonic_s"] - wall, plant["end_monotonic_s"])
    )
    return {
        f.name.split(".")[0]: cpu_in_window(json.loads(f.read_text()), *window)
        for f in sorted(cpu_log.glob("*.cpu.json"))
    }


def holdups(cpu_log: Path) -> dict[str, tuple[float, float, float, float]]:
    """What held each process up between the plant's first and last sample.

    Per process (its CPU log): the longest garbage collection (ms; those longer than the log's
    ``longer_than_s`` are listed), and the median and largest run-queue wait of its main thread
    within one 0.1 s sample of the log (ms: runnable, not running; on a virtual machine also
    the wake-up of an idle virtual CPU), and that wait per time it got a CPU (us: what each
    wake-up costs it on average). Missing fields give NaN.
    """
    plant = json.loads((cpu_log / "plant_sim.cpu.json").read_text())
    t0, t1 = plant.get("run_window") or (-math.inf, math.inf)
    out = {}
    for f in sorted(cpu_log.glob("*.cpu.json")):
        usage = json.loads(f.read_text())
        long = [d for t, d, _ in usage.get("gc", {}).get("long", []) if t0 <= t <= t1]
        wait = np.asarray(usage.get("run_queue_wait", []), dtype=float).reshape(-1, 3)
        wait = wait[(wait[:, 0] >= t0) & (wait[:, 0] <= t1)]
        steps = np.diff(wait[:, 1]) * 1e3 if len(wait) > 1 else np.array([math.nan])
        gc_ms = max(long) * 1e3 if long else (0.0 if "gc" in usage else math.nan)
        total = wait[-1, 1:] - wait[0, 1:] if len(wait) > 1 else np.zeros(2)
        per_wake = total[0] / total[1] * 1e6 if total[1] else math.nan  # us per time on a CPU
        out[f.name.split(".")[0]] = (
            gc_ms, float(np.median(steps)), float(steps.max()), float(per_wake)
        )  # fmt: skip
    return out


def _holdup_line(mode: str, r: dict) -> str:
    held = r.get("holdups") or {}
    cells = ", ".join(
        f"{n} {g:.1f} / {w50:.1f} / {w:.1f} / {u:.0f}" for n, (g, w50, w, u) in held.items()
    )
    return (
        f"{'':>16} {mode}: longest gc ms / run-queue wait per 0.1 s median, max ms / per wake-up"
        f" us: {cells}"
    )


def _cpu_line(mode: str, r: dict, fs: float) -> str:
    """Per-node CPU per processed sample of one run and mode, the plant excepted (item 4)."""
    cpu, processed = r.get("cpu"), r.get("processed", 0)
    if not cpu or not processed:
        return f"{'':>16} {mode}: no CPU logs or no coefficients in the bag"
    nodes = {n: c for n, c in cpu.items() if n != "plant_sim"}
    cells = ", ".join(f"{n} {c / processed * 1e6:.0f}" for n, c in nodes.items())
    total = sum(nodes.values()) / processed * 1e6
    return (
        f"{'':>16} {mode}: us of CPU per processed sample ({processed} of "
        f"{r.get('produced', 0)}): {cells}; node set {total:.0f} of the {1e6 / fs:.0f} budget "
        f"({total * fs / 1e6:.0%})"
    )


def run_mode(
    scenario: Path,
    model: Path,
    mode: str,
    out: Path,
    env: dict | None = None,
    extra: list[str] | tuple[str, ...] = (),
    run_args: list[str] | tuple[str, ...] = (),
    hog: Hog | None = None,
) -> Path:
    """``amb-run`` the four nodes and the recorder in ``mode``; return the run folder.

    ``extra``: more ``--set`` items; ``run_args``: more amb-run arguments (``--composed``);
    ``hog``: armed when amb-run is launched, disarmed when it ends.
    """
    sets = [f"wavelet_controller.model_file:={model}", "wavelet_controller.start_mode:=active",
            f"plant_sim.mode:={mode}", *extra]  # fmt: skip
    if hog is not None:
        hog.arm()
    try:
        run_checked([sys.executable, "-m", "amb_apps.run_cli", "--scenario", str(scenario),
              "--out", str(out), "--controller", "transient", "--quiet",
              *[a for s in sets for a in ("--set", s)], *run_args], env=env)  # fmt: skip
    finally:
        if hog is not None:
            hog.disarm()
    return out


def hog_windows(out: Path, cpu_log: Path, hog: Hog, spr: int, total: int) -> dict:
    """Periods controlled before, during and after the hog, from the run's bag.

    A period is controlled when all its samples are in the bag and none carries
    ``STATUS_COMMAND_MISSING``. The hog's monotonic window is put on the run's time axis with
    the plant's first sample (``run_window`` of its CPU log; realtime, ``time_scale`` 1).
    ``total``: the samples the plant produced (the bag's shortfall is counted).
    """
    from amb_msgs.msg import Measurement

    from amb_tools.bag_read import read_bag

    meas = read_bag(out / "bag").measurements
    wall0 = json.loads((cpu_log / "plant_sim.cpu.json").read_text())["run_window"][0]
    if hog.window is None:
        return {"lost": total - len(meas.sample_index)}
    on, off = (t - wall0 for t in hog.window)
    period = meas.time[spr] - meas.time[0] if len(meas.time) > spr else float("nan")
    n_periods = total // spr  # whole periods only: a partial last one is never "controlled"
    k = meas.sample_index[meas.sample_index < n_periods * spr] // spr
    present = np.bincount(k, minlength=n_periods)
    flagged = (meas.status[: len(k)] & Measurement.STATUS_COMMAND_MISSING) > 0
    missing = np.bincount(k, weights=flagged, minlength=n_periods)
    controlled = (present == spr) & (missing == 0)
    commanded = np.clip(present - missing, 0, None) / spr  # share of each period's samples
    start = np.arange(n_periods) * period
    settled = start >= 4 * period  # the first delay_periods have no command by design

    def frac(mask):
        return float(controlled[mask].mean()) if np.any(mask) else float("nan")

    during = settled & (start >= on) & (start + period <= off)
    later = np.flatnonzero(~controlled & (start >= off))
    return {
        "hog_on": on,
        "hog_off": off,
        "before": frac(settled & (start < on - period)),
        "during": frac(during),
        "during_samples": float(commanded[during].mean()) if np.any(during) else float("nan"),
        "after": frac(start >= off + 2 * period),
        "recover": float((start[later[-1]] + period - off) / period) if later.size else 0.0,
        # run s of each period without a command from 2 periods after the hog
        "uncontrolled_after": start[later[start[later] >= off + 2 * period]].tolist(),
        "lost": total - len(meas.sample_index),
    }


def case(
    hz: float,
    spr: int,
    duration: float,
    work: Path,
    repeat: int = 1,
    run_args: list[str] | tuple[str, ...] = (),
    hog: tuple[float, float] | None = None,
    extra: list[str] | tuple[str, ...] = (),
) -> list[dict]:
    """Run one speed/sampling case ``repeat`` times; return the plant's numbers of each run.

    ``hog``: (start, seconds) of a CPU hog in each realtime run (:func:`hog_windows`);
    ``extra``: more ``amb-run --set`` items (:func:`run_mode`).
    """
    scenario, model = prepare(hz, spr, duration, work)
    runs = []
    for i in range(repeat):
        result = {"hz": hz, "samples_per_rev": spr, "fs": hz * spr}
        for mode in ("lockstep", "realtime"):
            hogged = Hog(*hog) if hog is not None and mode == "realtime" else None
            env = dict(os.environ)
            cpu_log = work / f"cpu_{mode}_{hz:g}_{i}"
            env["AMB_CPU_LOG"] = str(cpu_log)
            out = run_mode(scenario, model, mode, work / f"{mode}_{hz:g}_{i}", env=env,
                           extra=extra, run_args=run_args, hog=hogged)  # fmt: skip
            log = (out / "logs" / "plant_sim.log").read_text()
            m = COMPLETE.search(log)
            if m is None:
                raise SystemExit(f"no completion line in {out / 'logs' / 'plant_sim.log'}")
            result[mode] = {k: float(v) for k, v in m.groupdict().items() if v is not None}
            control = CONTROL.search(log)
            if control is not None:
                result[mode].update(
                    {k: float(v) for k, v in control.groupdict().items() if v is not None}
                )
            result[mode]["cpu"] = node_cpu(cpu_log, result[mode]["wall"])
            result[mode]["holdups"] = holdups(cpu_log)
            result[mode]["processed"] = processed_samples(out / "bag")
            result[mode]["produced"] = round(hz * spr * duration)
            counts = COUNTS.search(log)
            result[mode].update(
                {k: int(v) for k, v in counts.groupdict().items()} if counts else {}
            )
            partial, samples = PARTIAL.search(log), SAMPLES.search(log)
            result[mode]["partial"] = int(partial.group(1)) if partial else 0
            publication = PUBLICATION.search(log)
            if publication is not None:
                result[mode]["pub_max"] = float(publication.group(1))
            write = WRITE.search(log)
            if write is not None:
                result[mode]["write_max"] = float(write.group(1))
            result[mode]["commanded"] = (  # without partial periods, the periods controlled
                float(samples.group(1)) if samples else result[mode].get("controlled", math.nan)
            )
            if hogged is not None:
                result["hog"] = hog_windows(out, cpu_log, hogged, spr, result[mode]["produced"])
        result["load"] = os.getloadavg()[0]
        runs.append(result)
    return runs


def _row(label: str, r: dict) -> str:
    rt, nan = r["realtime"], float("nan")
    return (
        f"{label:>16} {r['lockstep']['rtf']:>13.2f} {rt.get('p50', nan):>10.2f} "
        f"{rt.get('p99', nan):>8.2f} {rt.get('frac', nan) / 100:>11.1%} "
        f"{rt.get('controlled', nan) / 100:>11.1%} {rt.get('arr99', nan):>+11.2f} "
        f"{rt.get('missing', -1):>8d} {rt.get('late', -1):>5d} {rt.get('partial', -1):>8d} "
        f"{rt.get('commanded', nan) / 100:>12.1%} {rt.get('pub_max', nan):>11.2f} "
        f"{rt.get('write_max', nan):>13.2f} {r['load']:>6.1f}"
    ) + _hog_cells(r.get("hog"))


def _hog_cells(h: dict | None) -> str:
    if h is None:
        return ""
    nan = float("nan")
    return (
        f" {h.get('hog_on', nan):>5.1f}-{h.get('hog_off', nan):<5.1f} {h.get('before', nan):>7.1%}"
        f" {h.get('during', nan):>7.1%} {h.get('during_samples', nan):>8.1%}"
        f" {h.get('after', nan):>7.1%} "
        f"{h.get('recover', nan):>8.1f} {h['lost']:>5d}"
    )


def main() -> None:
    """Run each case ``--repeat`` times, lock-step and realtime; print every run and the load."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=8.0, help="simulated s per run")
    ap.add_argument("--cases", default="11:64,67:32", help="speed_hz:samples_per_rev,...")
    ap.add_argument("--repeat", type=int, default=1, help="runs per case (median printed)")
    ap.add_argument(
        "--composed", action="store_true", help="filterbank, monitor, controller in one process"
    )
    ap.add_argument(
        "--apart", action="append", default=[], help="with --composed: amb-run --apart NODE"
    )
    ap.add_argument("--nice", action="append", default=[], help="amb-run --nice NODE=N")
    ap.add_argument(
        "--rt-priority", action="append", default=[], help="amb-run --rt-priority PROCESS=P"
    )
    ap.add_argument("--udp", action="append", default=[], help="amb-run --udp PROCESS")
    ap.add_argument("--shm", action="append", default=[], help="amb-run --shm PROCESS")
    ap.add_argument(
        "--set", action="append", default=[], help="amb-run --set NODE.PARAM:=VALUE (repeatable)"
    )
    ap.add_argument(
        "--hog",
        help="START:SECONDS: one core busy from START s after each realtime launch, SECONDS long",
    )
    ap.add_argument("--keep", help="keep the runs' folders (bags, logs, CPU logs) here")
    args = ap.parse_args()
    hog = None
    if args.hog:
        try:
            hog = tuple(float(v) for v in args.hog.split(":"))
            if len(hog) != 2 or min(hog) < 0:
                raise ValueError
        except ValueError:
            ap.error(f"--hog {args.hog!r}: expected START:SECONDS, two numbers >= 0")
    run_args = ["--composed"] if args.composed else []
    run_args += [a for n in args.apart for a in ("--apart", n)]
    run_args += [a for n in args.nice for a in ("--nice", n)]
    run_args += [a for n in args.rt_priority for a in ("--rt-priority", n)]
    run_args += [a for n in args.udp for a in ("--udp", n)]
    run_args += [a for n in args.shm for a in ("--shm", n)]
    apart = f", {', '.join(args.apart)} apart" if args.apart else ""
    apart += f", nice {' '.join(args.nice)}" if args.nice else ""
    apart += f", SCHED_FIFO {' '.join(args.rt_priority)}" if args.rt_priority else ""
    apart += f", UDP {' '.join(args.udp)}" if args.udp else ""
    apart += f", shared memory {' '.join(args.shm)}" if args.shm else ""
    apart += f", set {' '.join(args.set)}" if args.set else ""
    print(f"deployment: {'composed (wavelet_stack)' if args.composed else 'one process per node'}"
          f"{apart}")  # fmt: skip
    cases = [tuple(c.split(":")) for c in args.cases.split(",")]
    print(f"{'case / run':>16} {'lockstep RTF':>13} {'rt p50 ms':>10} {'p99 ms':>8} "
          f"{'p99/period':>11} {'controlled':>11} {'arr p99 ms':>11} {'missing':>8} "
          f"{'late':>5} {'partial':>8} {'samples ctl':>12} {'pub max ms':>11} "
          f"{'write max ms':>13} {'load':>6}"
          + (f" {'hog s (run)':>11} {'before':>7} {'during':>7} {'(samples)':>8} {'after':>7} "
             f"{'recover':>8} "
             f"{'lost':>5}" if hog else ""))  # fmt: skip
    if args.keep:
        Path(args.keep).mkdir(parents=True, exist_ok=True)
    folder = contextlib.nullcontext(args.keep) if args.keep else tempfile.TemporaryDirectory()
    with folder as tmp:
        for hz, spr in cases:
            runs = case(
                float(hz), int(spr), args.duration, Path(tmp), args.repeat, run_args, hog, args.set
            )
            for i, r in enumerate(runs):
                print(_row(f"{hz} Hz x {spr} #{i + 1}", r), flush=True)
                for mode in ("lockstep", "realtime"):
                    print(_cpu_line(mode, r[mode], r["fs"]), flush=True)
                print(_holdup_line("realtime", r["realtime"]), flush=True)
                late = r.get("hog", {}).get("uncontrolled_after")
                if late:
                    shown = ", ".join(f"{t:.2f}" for t in late[:12])
                    more = f" and {len(late) - 12} more" if len(late) > 12 else ""
                    print(f"{'':>16} uncontrolled after the hog, run s: {shown}{more}", flush=True)
            if len(runs) > 1:
                med = {
                    "lockstep": {"rtf": statistics.median(r["lockstep"]["rtf"] for r in runs)},
                    "realtime": {
                        k: statistics.median(r["realtime"].get(k, float("nan")) for r in runs)
                        for k in (
                            "p50",
                            "p99",
                            "frac",
                            "controlled",
                            "arr99",
                            "commanded",
                            "pub_max",
                            "write_max",
                        )
                    },
                    "load": statistics.median(r["load"] for r in runs),
                }
                if hog:
                    med["hog"] = {
                        k: statistics.median(r["hog"].get(k, float("nan")) for r in runs)
                        for k in (
                            "hog_on",
                            "hog_off",
                            "before",
                            "during",
                            "during_samples",
                            "after",
                            "recover",
                        )
                    }
                    med["hog"]["lost"] = round(statistics.median(r["hog"]["lost"] for r in runs))
                med["realtime"]["missing"] = round(
                    statistics.median(r["realtime"].get("missing", -1) for r in runs)
                )
                for k in ("late", "partial"):
                    med["realtime"][k] = round(
                        statistics.median(r["realtime"].get(k, -1) for r in runs)
                    )
                print(_row(f"{hz} Hz x {spr} median", med), flush=True)
    print(
        "targets (#17): lock-step RTF >= 2 at 67 Hz x 32, >= 3 at 11 Hz x 64; realtime: 0 missing, "
        "0 late, p99 <= 50% of the period"
        + ("; hog: >= 90% controlled during it, recover <= 2 periods, 0 lost" if hog else "")
    )


if __name__ == "__main__":
    main()
