"""
Benchmark of the plant core: simulated seconds per wall-clock second.

Cases (14-element rig, default internal rate from config/rig.yaml): 11 Hz at 64 samples/rev
and 67 Hz at 32 samples/rev, each without contact (residual unbalance + a mass loss) and with
a contact event (auxiliary bearing AB1 misaligned into the orbit for ~0.1 s). Each case is run
``--repeats`` times after a warm-up that builds the cached discretisation; the median is
printed, with the one-off discretisation time, the share of samples integrated step by step,
and the ratio of the two speeds measured in the same run.

Run: ``python bench/plant_sim.py [--seconds 4] [--repeats 5]``.

The matrices are small (128 states), so OpenBLAS threads only add synchronisation cost, which
on a shared 2-core machine can cost a factor 2-5: the script pins ``OPENBLAS_NUM_THREADS=1``
unless it is set already (``OPENBLAS_NUM_THREADS=2 python bench/plant_sim.py`` to compare).
The ``plant_sim`` node should run with the same setting.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy is imported
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from amb_common.rig import load_rig
from amb_plant_sim.scenario import scenario_from_dict
from amb_plant_sim.simulator import PlantSimulator

TARGET = 20.0  # x real time, without contact and (issue 16) with it


def _events(contact: bool, seconds: float) -> list[dict]:
    ev = [
        {"kind": "unbalance", "disk": "D1", "me": 0.5e-3, "angle": 0.0},
        {"kind": "mass_loss", "time": 0.3 * seconds, "disk": "D1", "me": 1.0e-3, "angle": 1.0},
    ]
    if contact:
        ev.append(
            {
                "kind": "misalignment",
                "time": 0.5 * seconds,
                "bearing": "AB1",
                "dx": 0.0,
                "dy": 0.74e-3,
                "ramp": 0.05,
                "hold": 0.1,
                "return_time": 0.05,
            }
        )
    return ev


def run_case(rig, speed_hz: float, spr: int, contact: bool, seconds: float, repeats: int):
    """Return (median x real time, build s, step-by-step share, contact samples)."""
    sc = scenario_from_dict(
        {"speed": {"hz": speed_hz}, "duration": seconds, "events": _events(contact, seconds)},
        rig,
    )
    sim = PlantSimulator(rig, sc, spr)
    t0 = time.perf_counter()
    sim.advance(1)
    build = time.perf_counter() - t0
    n = round(seconds * sim.fs)
    rates = []
    blk = None
    for _ in range(repeats):
        sim.reset()
        t0 = time.perf_counter()
        blk = sim.advance(n)
        rates.append(seconds / (time.perf_counter() - t0))
    slow = float(blk.truth["step_by_step"].mean())
    n_contact = int(blk.truth["contact"].any(axis=1).sum())
    return statistics.median(rates), build, slow, n_contact


def main(argv: list[str] | None = None) -> int:
    """Print the benchmark table."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seconds", type=float, default=4.0, help="simulated seconds per run")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    rig = load_rig()
    print(
        f"plant core benchmark: {rig.shaft.elements} elements, internal rate >= "
        f"{rig.simulation.internal_rate_min:.0f} Hz, {args.seconds} s simulated, "
        f"median of {args.repeats}, OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']}"
    )
    print(f"{'case':34s} {'x real time':>12s} {'build s':>8s} {'stepwise':>9s} {'contact':>8s}")
    results = {}
    for speed, spr in ((11.0, 64), (67.0, 32)):
        for contact in (False, True):
            r, b, slow, nc = run_case(rig, speed, spr, contact, args.seconds, args.repeats)
            name = f"{speed:.0f} Hz, {spr} samples/rev, {'contact' if contact else 'no contact'}"
            results[(speed, contact)] = r
            print(f"{name:34s} {r:12.1f} {b:8.3f} {100 * slow:8.1f}% {nc:8d}")
    ratio = results[(11.0, False)] / results[(67.0, False)]
    print(f"ratio 11 Hz / 67 Hz without contact (same run): {ratio:.2f}")
    worst = min(results[(11.0, False)], results[(67.0, False)])
    verdict = "met" if worst >= TARGET else "MISSED"
    print(f"target >= {TARGET:.0f}x real time without contact: {verdict}")
    worst = min(results[(11.0, True)], results[(67.0, True)])
    verdict = "met" if worst >= TARGET else "MISSED"
    print(f"target >= {TARGET:.0f}x real time with a contact: {verdict} (slowest {worst:.1f}x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
