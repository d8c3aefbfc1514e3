"""
Benchmark of the fault monitor core: false alarms in long healthy noisy running, and speed.

A healthy scenario of ``config/scenarios/faults`` (residual unbalance on D1 and D4, 0.2 um
probe noise; default ``healthy_11hz.yaml``, the rig's first critical speed, section 2.1) is
simulated for ``--minutes`` simulated minutes in chunks of ``--chunk`` seconds with the plant
core (``amb_plant_sim``), analysed by the filterbank core (``FilterbankAdapter``, the same
front end and causal filterbank as the ``wavelet_filterbank`` node) and fed to
:class:`amb_fault_monitor.monitor.FaultMonitor`. Printed:

- events (every one is a false alarm), unconfirmed episodes (isolated crossings dropped after
  ``confirm_revs``), when calibration ended and how often the window slid on (start-up
  transient);
- samples/s of the monitor core alone and of filterbank + monitor, and the real-time factor
  (simulated seconds per wall-clock second of filterbank + monitor; > 1 keeps up with the rig).
  The median over chunks is printed with the min and max.

With ``--provisional REVS`` the monitor publishes provisional classes and is fed the
displacements for its jump test and the change's shape (:mod:`amb_fault_monitor.provisional`),
as the node feeds it.

Run: ``python bench/fault_monitor.py [--minutes 10] [--scenario healthy_67hz.yaml]
[--provisional 1.5]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy is imported
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from amb_apps.evaluation import load_case  # noqa: E402
from amb_common.rig import load_rig  # noqa: E402
from amb_fault_monitor.config import MonitorConfig  # noqa: E402
from amb_fault_monitor.monitor import FaultMonitor  # noqa: E402
from amb_fault_monitor.records import FilterbankAdapter  # noqa: E402
from amb_plant_sim.scenario import scenario_from_dict  # noqa: E402
from amb_plant_sim.simulator import PlantSimulator  # noqa: E402


def run(
    path: Path, minutes: float, chunk_s: float, wavelet: str, seed: int, provisional: float = 0.0
) -> dict:
    """Run the healthy scenario ``path`` for ``minutes``; return counts and timings."""
    rig = load_rig()
    scen_d, expect, _mon = load_case(path)
    if expect:
        raise SystemExit(f"{path} expects faults; pick a healthy scenario (expect: [])")
    scen_d = {**scen_d, "duration": 60.0 * minutes}
    scenario = scenario_from_dict(scen_d, rig)
    spr = int(scenario.samples_per_rev or 32)
    fs = spr * scenario.speed_hz
    sim = PlantSimulator(rig, scenario, spr, seed)
    adapter = FilterbankAdapter(spr, wavelet)
    monitor = FaultMonitor(MonitorConfig(spr, provisional_revs=provisional))
    total = round(60.0 * minutes * fs)
    per_chunk = max(spr, round(chunk_s * fs))
    events = []
    sim_t = fb_t = mon_t = 0.0
    rates_mon, rates_all = [], []
    done = 0
    while done < total:
        n = min(per_chunk, total - done)
        t0 = time.perf_counter()
        block = sim.advance(n)
        t1 = time.perf_counter()
        recs = [
            adapter.step(
                int(block.sample_index[i]), block.displacement[i], block.angle[i], block.omega[i]
            )
            for i in range(n)
        ]
        t2 = time.perf_counter()
        for i, r in enumerate(recs):
            monitor.displacements(r.sample_index, block.displacement[i])
            events += monitor.step(r)
        t3 = time.perf_counter()
        sim_t += t1 - t0
        fb_t += t2 - t1
        mon_t += t3 - t2
        rates_mon.append(n / (t3 - t2))
        rates_all.append(n / (t3 - t1))
        done += n
    return {
        "scenario": scenario.name,
        "speed_hz": scenario.speed_hz,
        "samples_per_rev": spr,
        "fs": fs,
        "samples": total,
        "simulated_s": total / fs,
        "events": events,
        "unconfirmed": monitor.unconfirmed,
        "calibration_end_s": (monitor.calibration_end or 0) / fs,
        "calibration_retries": monitor.calibration_retries,
        "sim_wall_s": sim_t,
        "filterbank_wall_s": fb_t,
        "monitor_wall_s": mon_t,
        "rates_mon": rates_mon,
        "rates_all": rates_all,
    }


def main() -> int:
    """Parse the arguments, run, print."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, default=10.0, help="simulated minutes")
    ap.add_argument("--scenario", default="healthy_11hz.yaml", help="file in the faults folder")
    ap.add_argument("--chunk", type=float, default=10.0, help="simulated seconds per chunk")
    ap.add_argument("--wavelet", default="haar")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument(
        "--provisional", type=float, default=0.0, help="provisional_revs (0: none, the default)"
    )
    a = ap.parse_args()
    path = Path(a.scenario)
    if not path.exists():
        path = ROOT / "config" / "scenarios" / "faults" / a.scenario
    r = run(path, a.minutes, a.chunk, a.wavelet, a.seed, a.provisional)
    med = statistics.median
    print(
        f"scenario {r['scenario']}: {r['speed_hz']:.2f} Hz, {r['samples_per_rev']} samples/rev, "
        f"fs {r['fs']:.1f} Hz, wavelet {a.wavelet}, seed {a.seed}, provisional_revs "
        f"{a.provisional:g}"
    )
    print(f"simulated {r['simulated_s']:.1f} s = {r['samples']} samples")
    print(
        f"calibration ended at {r['calibration_end_s']:.2f} s "
        f"({r['calibration_retries']} slides of the window during the start-up transient)"
    )
    print(f"false alarms (events): {len(r['events'])}; unconfirmed episodes: {r['unconfirmed']}")
    for e in r["events"]:
        print(f"  {e.fault_type.name} at {e.detection_sample_index / r['fs']:.3f} s: {e.evidence}")
    rm, ra = r["rates_mon"], r["rates_all"]
    print(
        f"monitor core: median {med(rm):.0f} samples/s (min {min(rm):.0f}, max {max(rm):.0f}) "
        f"= {med(rm) / r['fs']:.1f} x real time"
    )
    print(
        f"filterbank + monitor: median {med(ra):.0f} samples/s (min {min(ra):.0f}, "
        f"max {max(ra):.0f}) = real-time factor {med(ra) / r['fs']:.1f}"
    )
    print(
        f"wall: plant sim {r['sim_wall_s']:.1f} s, filterbank {r['filterbank_wall_s']:.1f} s, "
        f"monitor {r['monitor_wall_s']:.1f} s"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
