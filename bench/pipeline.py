"""Benchmark: the four-node loop over DDS (amb-run), lock-step real-time factor and the
command latency in realtime mode.

For each case (running speed, samples per revolution): a wavelet model from the FE route
(``amb-sim --model fe``), then
1. lock-step: ``amb-run`` with plant_sim, wavelet_filterbank, fault_monitor,
   wavelet_controller (transient, ACTIVE) and the recorder; the real-time factor is simulated
   time over wall time from the first sample to the last (plant_sim's own measurement);
2. realtime: the same nodes with ``plant_sim.mode:=realtime``; plant_sim measures, for each
   command, the wall time from the last sample of the period it is based on to its arrival
   (median, p99, as a fraction of the control period).
Numbers come from one run per case on whatever else the machine is doing: read them as
ratios to the target, not as absolutes.

    python bench/pipeline.py [--duration 8] [--cases 11:64,67:32]
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
COMPLETE = re.compile(
    r"in (?P<wall>[\d.]+) s wall, real-time factor (?P<rtf>[\d.]+)"
    r"(?:; command latency p50 (?P<p50>[\d.]+) ms, p99 (?P<p99>[\d.]+) ms \((?P<frac>[\d.]+)%)?"
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
    _run([sys.executable, "-m", "amb_controller.sim_cli", "--scenario", str(scenario),
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
) -> Path:
    """``amb-run`` the four nodes and the recorder in ``mode``; return the run folder."""
    sets = [f"wavelet_controller.model_file:={model}", "wavelet_controller.start_mode:=active",
            f"plant_sim.mode:={mode}", *extra]  # fmt: skip
    _run([sys.executable, "-m", "amb_tools.run_cli", "--scenario", str(scenario),
          "--out", str(out), "--controller", "transient", "--quiet",
          *[a for s in sets for a in ("--set", s)]], env=env)  # fmt: skip
    return out


def case(hz: float, spr: int, duration: float, work: Path) -> dict:
    """Run one speed/sampling case; return the plant's measured numbers."""
    scenario, model = prepare(hz, spr, duration, work)
    result = {"hz": hz, "samples_per_rev": spr, "fs": hz * spr}
    for mode in ("lockstep", "realtime"):
        out = run_mode(scenario, model, mode, work / f"{mode}_{hz:g}")
        log = (out / "logs" / "plant_sim.log").read_text()
        m = COMPLETE.search(log)
        if m is None:
            raise SystemExit(f"no completion line in {out / 'logs' / 'plant_sim.log'}")
        result[mode] = {k: float(v) for k, v in m.groupdict().items() if v is not None}
    return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=8.0, help="simulated s per run")
    ap.add_argument("--cases", default="11:64,67:32", help="speed_hz:samples_per_rev,...")
    args = ap.parse_args()
    cases = [tuple(c.split(":")) for c in args.cases.split(",")]
    print(f"{'case':>14} {'fs Hz':>7} {'lockstep RTF':>13} {'realtime p50 ms':>16} "
          f"{'p99 ms':>8} {'p99/period':>11}")  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        for hz, spr in cases:
            r = case(float(hz), int(spr), args.duration, Path(tmp))
            rt = r["realtime"]
            print(
                f"{hz:>5} Hz x {spr:>3} {r['fs']:>7.0f} {r['lockstep']['rtf']:>13.2f} "
                f"{rt.get('p50', float('nan')):>16.2f} {rt.get('p99', float('nan')):>8.2f} "
                f"{rt.get('frac', float('nan')) / 100:>11.1%}",
                flush=True,
            )
    print("targets: lock-step RTF >= 1.0 at both speeds; realtime p99 < 10% of the period at 67 Hz")


if __name__ == "__main__":
    main()
