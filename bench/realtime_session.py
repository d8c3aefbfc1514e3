"""
Benchmark: a realtime session as on a rig, on-line identification and then transient control.

Issue 17's third target: at 11 Hz x 64 in ``realtime``, identification and then transient
control with no missing command, and the fault monitor never more than one period behind the
stream. Each run is two ``amb-run`` calls with ``plant_sim.mode:=realtime`` and every node
(the fault monitor too):

1. identification (``config/scenarios/identification_first_critical.yaml`` at ``--hz``:
   PID only, the controller steps each control coefficient and writes the model file);
2. the 430 g cm mass loss of ``mass_loss_first_critical.yaml`` at ``--hz``, the transient
   controller ACTIVE with that model.

Printed per phase and run: the plant's command counts (``missing``: no command by the period's
start; ``late``: arrived after; ``partial``: of those, applied to the rest of their period), the
periods controlled, and the fault monitor's lag: at each of
its ``/diagnostics`` reports (every ``--status-period`` s), the last sample the plant had
released by the report's stamp less the monitor's ``last_sample``, in periods (largest and
median over the run; :func:`monitor_lag`); then the 1-minute load.

    python bench/realtime_session.py [--hz 11] [--spr 64] [--repeat 3] [--separate]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pipeline import CONTROL, COUNTS, PARTIAL, ROOT, run_checked

sys.path.insert(0, str(ROOT))


def _scenario(name: str, hz: float, spr: int, work: Path) -> Path:
    """A copy of ``config/scenarios/<name>.yaml`` at ``hz`` and ``spr``."""
    data = yaml.safe_load((ROOT / "config" / "scenarios" / f"{name}.yaml").read_text())
    data["speed"], data["samples_per_rev"] = {"hz": hz}, spr
    path = work / f"{name}_{hz:g}hz.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def _amb_run(scenario: Path, out: Path, sets: list[str], composed: bool) -> str:
    """Run ``amb-run`` in realtime; return the plant's log."""
    cmd = [sys.executable, "-m", "amb_apps.run_cli", "--scenario", str(scenario), "--out",
           str(out), "--controller", "transient", "--quiet",
           *[a for s in ["plant_sim.mode:=realtime", *sets] for a in ("--set", s)]]  # fmt: skip
    run_checked([*cmd, "--composed"] if composed else cmd)
    return (out / "logs" / "plant_sim.log").read_text()


def monitor_lag(bag: Path, spr: int) -> np.ndarray:
    """The fault monitor's lag behind the plant's stream at each of its reports, periods.

    The plant publishes sample n at ``wall0 + t_n`` (realtime, ``time_scale`` 1); each of its
    reports, stamped T, gives ``published_time``, the last sample's t, so ``wall0 <= T - t``
    (the report follows the sample). The smallest of these over the run is ``wall0`` to within
    the shortest delay between a sample and a report. At a monitor report stamped T the plant
    had published the samples up to ``(T - wall0) fs``; the lag is that less the monitor's
    ``last_sample`` (an upper bound, by that delay).
    """
    from rosbags.highlevel import AnyReader

    from amb_common import topics
    from amb_tools.bag_types import typestore

    plant: list[float] = []  # T - published_time
    last_published = 0.0  # t of the plant's last sample
    monitor: list[tuple[float, int]] = []  # (T, last sample)
    fs = None
    with AnyReader([bag], default_typestore=typestore()) as reader:
        conns = [c for c in reader.connections if c.topic == topics.DIAGNOSTICS]
        for conn, _t, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
            for status in msg.status:
                values = {kv.key: kv.value for kv in status.values}
                if status.name == "plant_sim" and float(values["published_time"]) >= 0:
                    plant.append(stamp - float(values["published_time"]))
                    last_published = max(last_published, float(values["published_time"]))
                    fs = float(values["speed_hz"]) * spr
                elif status.name == "fault_monitor" and values.get("last_sample") not in (
                    None, "", "None"
                ):  # fmt: skip
                    monitor.append((stamp, int(values["last_sample"])))
    if not plant or not monitor:
        return np.array([])
    wall0 = min(plant)
    # after the plant's last sample the stream has ended: published no further
    end = round(last_published * fs)
    return np.array([(min(int((t - wall0) * fs), end) - last) / spr for t, last in monitor])


def phase_numbers(log: str, bag: Path, spr: int) -> dict:
    """Command counts, periods controlled and the monitor's lag of one ``amb-run``."""
    counts = COUNTS.search(log)
    partial = PARTIAL.search(log)
    controlled = CONTROL.search(log)
    lag = monitor_lag(bag, spr)
    return {
        **({k: int(v) for k, v in counts.groupdict().items()} if counts else {}),
        "partial": int(partial["partial"]) if partial else 0,
        "controlled": float(controlled["controlled"]) if controlled else float("nan"),
        "lag_max": float(lag.max()) if lag.size else float("nan"),
        "lag_median": float(np.median(lag)) if lag.size else float("nan"),
        "reports": int(lag.size),
    }


def session(hz: float, spr: int, work: Path, composed: bool, status_period: float) -> dict:
    """One identification run and one transient run; their numbers."""
    ident = _scenario("identification_first_critical", hz, spr, work)
    loss = _scenario("mass_loss_first_critical", hz, spr, work)
    model = work / "model.npz"
    # the monitor's and the plant's reports, often (monitor_lag)
    monitor = [f"{n}.status_period:={status_period}" for n in ("fault_monitor", "plant_sim")]
    log = _amb_run(ident, work / "identification", [
        "wavelet_controller.start_mode:=identify", f"wavelet_controller.model_file_out:={model}",
        *monitor], composed)  # fmt: skip
    if not model.exists():
        raise SystemExit(f"identification wrote no model: see {work / 'identification' / 'logs'}")
    out = {"identification": phase_numbers(log, work / "identification" / "bag", spr)}
    log = _amb_run(loss, work / "transient", [
        f"wavelet_controller.model_file:={model}", "wavelet_controller.start_mode:=active",
        *monitor], composed)  # fmt: skip
    out["transient"] = phase_numbers(log, work / "transient" / "bag", spr)
    out["load"] = os.getloadavg()[0]
    return out


def main(argv: list[str] | None = None) -> int:
    """Run the sessions and print one line per phase and run, then the medians."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hz", type=float, default=11.0, help="running speed, Hz")
    ap.add_argument("--spr", type=int, default=64, help="samples per revolution")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--separate", action="store_true", help="every node in its own process")
    ap.add_argument("--status-period", type=float, default=0.2, help="monitor reports, s")
    ap.add_argument("--keep", type=Path, default=None, help="keep the runs in this folder")
    args = ap.parse_args(argv)
    deployment = "separate processes" if args.separate else "composed (wavelet_stack)"
    load = os.getloadavg()[0]
    print(f"realtime session at {args.hz:g} Hz x {args.spr}, {deployment}, load {load:.2f}")
    header = (f"{'phase / run':>20} {'applied':>8} {'missing':>8} {'late':>5} {'partial':>8} "
              f"{'controlled':>11} "
              f"{'lag max':>8} {'lag p50':>8} {'reports':>8} {'load':>5}")  # fmt: skip
    print(header + "   (lag: periods the fault monitor was behind the plant's stream)")
    rows: dict[str, list[dict]] = {"identification": [], "transient": []}
    with tempfile.TemporaryDirectory() as tmp:
        root = args.keep or Path(tmp)
        for i in range(args.repeat):
            work = root / f"run_{i}"
            work.mkdir(parents=True)
            result = session(args.hz, args.spr, work, not args.separate, args.status_period)
            for phase in rows:
                r = result[phase]
                rows[phase].append(r)
                print(_line(f"{phase} #{i + 1}", r, result["load"]), flush=True)
    for phase, rs in rows.items():
        med = {k: statistics.median(r.get(k, float("nan")) for r in rs) for k in rs[0]}
        print(_line(f"{phase} median", med, float("nan")))
    print("target (#17): 0 missing commands in both phases; lag max <= 1 period")
    return 0


def _line(label: str, r: dict, load: float) -> str:
    nan = float("nan")
    return (
        f"{label:>20} {r.get('applied', -1):>8.0f} {r.get('missing', -1):>8.0f} "
        f"{r.get('late', -1):>5.0f} {r.get('partial', -1):>8.0f} "
        f"{r.get('controlled', nan) / 100:>11.1%} "
        f"{r.get('lag_max', nan):>8.2f} {r.get('lag_median', nan):>8.2f} "
        f"{r.get('reports', 0):>8.0f} {load:>5.2f}"
    )


if __name__ == "__main__":
    raise SystemExit(main())
