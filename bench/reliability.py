"""Soak benchmark: the 67 Hz pipeline in lockstep over DDS for a long simulated time.

Starts plant_sim (67 Hz, ``--spr`` samples/rev, lockstep), wavelet_filterbank, fault_monitor,
wavelet_controller and the recorder as separate processes (the installed node executables).
The controller runs the transient law ACTIVE from a model built by ``amb-sim --model fe``
(``--controller off``: zero commands; the lock-step exchange runs every period either way).
It samples the resident memory
(``VmRSS`` from ``/proc``) of each every few seconds, and at the end prints: simulated and wall
time, samples the plant produced, samples in the bag (messages lost = difference), commands
missing/late/rejected (plant's log), memory after warm-up and its growth per process.

    source tools/env.sh && python bench/reliability.py --soak-minutes 30

The pass criteria of issue 8: messages lost 0, memory growth <= 10 % after warm-up.
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

from amb_common import topics


def rss_kib(pid: int) -> int:
    """Resident memory of a process in KiB (``VmRSS``), 0 if it has gone."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except OSError:
        pass
    return 0


def start(name: str, log_dir: Path, params: dict) -> tuple[subprocess.Popen, Path]:
    """Start a node executable with ``-p`` parameters; return the process and its log path."""
    args = [name, "--ros-args"]
    for k, v in params.items():
        text = str(v).lower() if isinstance(v, bool) else str(v)
        args += ["-p", f"{k}:={text}"]
    log = log_dir / f"{name}.log"
    proc = subprocess.Popen(args, stdout=open(log, "w"), stderr=subprocess.STDOUT)
    return proc, log


def main() -> int:
    """Soak the four nodes and report lost messages and memory growth (module docstring)."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--soak-minutes", type=float, default=30.0, help="simulated minutes")
    p.add_argument("--hz", type=float, default=67.0, help="running speed, Hz")
    p.add_argument("--spr", type=int, default=32, help="samples per revolution")
    p.add_argument("--sample-every", type=float, default=5.0, help="wall s between RSS samples")
    p.add_argument(
        "--controller", choices=("transient", "off"), default="transient", help="controller law"
    )
    args = p.parse_args()
    work = Path(tempfile.mkdtemp(prefix="amb-soak-"))
    duration = args.soak_minutes * 60.0
    scenario = work / "soak.yaml"
    scenario.write_text(
        yaml.safe_dump(
            {
                "name": "soak",
                "speed": {"hz": args.hz},
                "duration": duration,
                "samples_per_rev": args.spr,
                "measurement_noise": 2.0e-7,
                "events": [{"kind": "unbalance", "time": 0.0, "disk": "D1", "me": 1.0e-3}],
            }
        )
    )
    controller = {"samples_per_rev": args.spr}
    if args.controller == "transient":
        model_dir = work / "model"
        subprocess.run(
            [sys.executable, "-m", "amb_apps.sim_cli", "--scenario", str(scenario),
             "--controller", "transient", "--model", "fe", "--duration", "0.5", "--no-bag",
             "--out", str(model_dir)],
            check=True, capture_output=True,
        )  # fmt: skip
        controller.update(
            {"model_file": str(model_dir / "model.npz"), "start_mode": "active",
             "controller": "transient"}
        )  # fmt: skip
    bag = work / "bag"
    procs = {}
    procs["recorder"] = start(
        "recorder",
        work,
        {"output": str(bag), "topics": "['/amb/measurement', '/amb/control/command']"},
    )
    procs["wavelet_filterbank"] = start("wavelet_filterbank", work, {"samples_per_rev": args.spr})
    procs["fault_monitor"] = start("fault_monitor", work, {"samples_per_rev": args.spr})
    procs["wavelet_controller"] = start("wavelet_controller", work, controller)
    time.sleep(3.0)
    procs["plant_sim"] = start(
        "plant_sim",
        work,
        {"scenario_file": str(scenario), "samples_per_rev": args.spr, "wait_for_subscribers": 3},
    )
    wall0 = time.monotonic()
    memory: dict[str, list[tuple[float, int]]] = {name: [] for name in procs}
    plant = procs["plant_sim"][0]
    next_report = 60.0
    while plant.poll() is None:
        t = time.monotonic() - wall0
        for name, (proc, _) in procs.items():
            memory[name].append((t, rss_kib(proc.pid)))
        if t >= next_report:
            rss = ", ".join(f"{n} {s[-1][1] / 1024:.0f}" for n, s in memory.items())
            print(f"  {t / 60:5.1f} min wall; RSS MiB: {rss}", flush=True)
            next_report += 60.0
        time.sleep(args.sample_every)
    wall = time.monotonic() - wall0
    time.sleep(2.0)
    for name in ("wavelet_controller", "fault_monitor", "wavelet_filterbank", "recorder"):
        procs[name][0].send_signal(signal.SIGINT)
    for proc, _ in procs.values():
        proc.wait(60)
    plant_log = procs["plant_sim"][1].read_text()
    done = re.search(r"complete at t = ([\d.]+) s \((\d+) samples\).*commands: (.*)", plant_log)
    if done is None:
        print(plant_log[-3000:])
        return 1
    sim_time, n_samples = float(done.group(1)), int(done.group(2))
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
    in_bag = counts.get(topics.absolute(topics.MEASUREMENT), 0)
    print(f"soak: {args.hz:g} Hz, {args.spr} samples/rev, lockstep, controller {args.controller}")
    print(
        f"simulated {sim_time:.1f} s in {wall:.1f} s wall (real-time factor {sim_time / wall:.2f})"
    )
    print(f"samples: plant {n_samples}, recorder {in_bag}, lost {n_samples - in_bag}")
    print(f"commands in bag {counts.get('/amb/control/command', 0)}; plant: {done.group(3)}")
    for name, series in memory.items():
        series = [(t, r) for t, r in series if r > 0]
        if len(series) < 3:
            print(f"memory {name}: too few samples")
            continue
        warm = series[len(series) // 5]  # after the first fifth of the run
        last = series[-1]
        growth = (last[1] - warm[1]) / warm[1]
        print(
            f"memory {name}: {warm[1] / 1024:.1f} MiB at {warm[0]:.0f} s -> "
            f"{last[1] / 1024:.1f} MiB at {last[0]:.0f} s ({growth:+.1%})"
        )
    print(f"work folder {work}")
    return 0 if n_samples == in_bag else 1


if __name__ == "__main__":
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    raise SystemExit(main())
