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
   time).
Each case is run ``--repeat`` times (the model is made once); every run is printed with the
plant's command counts (``missing``: no command by the period's start; ``late``: arrived after)
and the machine's 1-minute load average at its end, then the median over the runs. Numbers
depend on whatever else the machine is doing: read them as ratios to the target, and compare
runs made under the same load.

    python bench/pipeline.py [--duration 8] [--cases 11:64,67:32] [--repeat 3]
        [--composed [--apart fault_monitor]] [--nice NODE=N]
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
COUNTS = re.compile(
    r"commands: applied (?P<applied>\d+), missing (?P<missing>\d+), late (?P<late>\d+)"
)
COMPLETE = re.compile(
    r"in (?P<wall>[\d.]+) s wall, real-time factor (?P<rtf>[\d.]+)"
    r"(?:; command latency p50 (?P<p50>[\d.]+) ms, p99 (?P<p99>[\d.]+) ms \((?P<frac>[\d.]+)%)?"
)
CONTROL = re.compile(
    r"periods controlled (?P<controlled>[\d.]+)%"
    r"(?:, command arrival - period start p50 (?P<arr50>[-+\d.]+) ms, p99 (?P<arr99>[-+\d.]+) ms)?"
)


def _run(cmd: list[str], env: dict | None = None) -> subprocess.CompletedProcess:
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
    _run([sys.executable, "-m", "amb_apps.sim_cli", "--scenario", str(scenario),
          "--controller", "transient", "--model", "fe", "--duration", "0.5", "--no-bag",
          "--out", str(model_dir)])  # fmt: skip
    return scenario, model_dir / "model.npz"


def run_mode(
    scenario: Path,
    model: Path,
    mode: str,
    out: Path,
    env: dict | None = None,
    extra: list[str] | tuple[str, ...] = (),
    run_args: list[str] | tuple[str, ...] = (),
) -> Path:
    """``amb-run`` the four nodes and the recorder in ``mode``; return the run folder.

    ``extra``: more ``--set`` items; ``run_args``: more amb-run arguments (``--composed``).
    """
    sets = [f"wavelet_controller.model_file:={model}", "wavelet_controller.start_mode:=active",
            f"plant_sim.mode:={mode}", *extra]  # fmt: skip
    _run([sys.executable, "-m", "amb_apps.run_cli", "--scenario", str(scenario),
          "--out", str(out), "--controller", "transient", "--quiet",
          *[a for s in sets for a in ("--set", s)], *run_args], env=env)  # fmt: skip
    return out


def case(
    hz: float,
    spr: int,
    duration: float,
    work: Path,
    repeat: int = 1,
    run_args: list[str] | tuple[str, ...] = (),
) -> list[dict]:
    """Run one speed/sampling case ``repeat`` times; return the plant's numbers of each run."""
    scenario, model = prepare(hz, spr, duration, work)
    runs = []
    for i in range(repeat):
        result = {"hz": hz, "samples_per_rev": spr, "fs": hz * spr}
        for mode in ("lockstep", "realtime"):
            out = run_mode(scenario, model, mode, work / f"{mode}_{hz:g}_{i}", run_args=run_args)
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
            counts = COUNTS.search(log)
            result[mode].update(
                {k: int(v) for k, v in counts.groupdict().items()} if counts else {}
            )
        result["load"] = os.getloadavg()[0]
        runs.append(result)
    return runs


def _row(label: str, r: dict) -> str:
    rt, nan = r["realtime"], float("nan")
    return (
        f"{label:>16} {r['lockstep']['rtf']:>13.2f} {rt.get('p50', nan):>10.2f} "
        f"{rt.get('p99', nan):>8.2f} {rt.get('frac', nan) / 100:>11.1%} "
        f"{rt.get('controlled', nan) / 100:>11.1%} {rt.get('arr99', nan):>+11.2f} "
        f"{rt.get('missing', -1):>8d} {rt.get('late', -1):>5d} {r['load']:>6.1f}"
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
    args = ap.parse_args()
    run_args = ["--composed"] if args.composed else []
    run_args += [a for n in args.apart for a in ("--apart", n)]
    run_args += [a for n in args.nice for a in ("--nice", n)]
    apart = f", {', '.join(args.apart)} apart" if args.apart else ""
    apart += f", nice {' '.join(args.nice)}" if args.nice else ""
    print(f"deployment: {'composed (wavelet_stack)' if args.composed else 'one process per node'}"
          f"{apart}")  # fmt: skip
    cases = [tuple(c.split(":")) for c in args.cases.split(",")]
    print(f"{'case / run':>16} {'lockstep RTF':>13} {'rt p50 ms':>10} {'p99 ms':>8} "
          f"{'p99/period':>11} {'controlled':>11} {'arr p99 ms':>11} {'missing':>8} "
          f"{'late':>5} {'load':>6}")  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        for hz, spr in cases:
            runs = case(float(hz), int(spr), args.duration, Path(tmp), args.repeat, run_args)
            for i, r in enumerate(runs):
                print(_row(f"{hz} Hz x {spr} #{i + 1}", r), flush=True)
            if len(runs) > 1:
                med = {
                    "lockstep": {"rtf": statistics.median(r["lockstep"]["rtf"] for r in runs)},
                    "realtime": {
                        k: statistics.median(r["realtime"].get(k, float("nan")) for r in runs)
                        for k in ("p50", "p99", "frac", "controlled", "arr99")
                    },
                    "load": statistics.median(r["load"] for r in runs),
                }
                med["realtime"]["missing"] = round(
                    statistics.median(r["realtime"].get("missing", -1) for r in runs)
                )
                med["realtime"]["late"] = round(
                    statistics.median(r["realtime"].get("late", -1) for r in runs)
                )
                print(_row(f"{hz} Hz x {spr} median", med), flush=True)
    print(
        "targets (#17): lock-step RTF >= 2 at 67 Hz x 32, >= 3 at 11 Hz x 64; realtime: 0 missing, "
        "0 late, p99 <= 50% of the period"
    )


if __name__ == "__main__":
    main()
