"""
``amb-modal``: natural frequencies, damping, critical speeds, sensitivity and chapter-2 plots.

Usage::

    amb-modal --rig config/rig.yaml [--free-free] [--speeds-hz 0,20,...] [--elements N]
              [--json] [--plot-dir DIR]

Prints, per running speed, the modes (damped natural frequency in Hz, damping ratio, whirl)
of the PID closed loop (or, with ``--free-free``, of the free rotor), the critical speeds and
the calibration record, and the peak sensitivity with its ISO 14839-3 zone at each bearing
axis. ``--plot-dir`` writes: campbell.png (figure 2.7 style), elements.png (2.6),
gain.png (2.13), singular_values.png (2.16), modes_free_free.png (2.4), modes_pid.png (2.15),
sensitivity.png.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from amb_common.errors import RigError
from amb_common.names import AXIS_NAMES
from amb_common.rig import DEFAULT_RIG_PATH, load_rig
from amb_plant_sim import analysis
from amb_plant_sim.modal import closed_loop_modes, critical_speeds, distinct_modes, free_free_modes
from amb_plant_sim.rotor import build_rotor


def _speeds(text: str) -> list[float]:
    try:
        vals = [float(v) for v in text.split(",") if v.strip()]
    except ValueError as exc:
        msg = f"--speeds-hz: expected numbers like 0,20,40: {exc}"
        raise argparse.ArgumentTypeError(msg) from exc
    if not vals or any(v < 0 for v in vals):
        raise argparse.ArgumentTypeError("--speeds-hz: give non-negative speeds in Hz")
    return vals


def build_report(rig, free_free: bool, speeds: list[float], elements: int | None, n_modes: int):
    """Everything printed by the tool, as a JSON-ready dict."""
    ne = rig.shaft.elements if elements is None else elements
    camp = analysis.campbell(
        rig, np.array(speeds), free_free=free_free, elements=ne, max_frequency_hz=np.inf
    )
    report = {
        "rig": rig.source,
        "model": "free_free" if free_free else "pid_closed_loop",
        "elements": ne,
        "speeds": [
            {"speed_hz": s, "modes": [m.as_dict() for m in ms[:n_modes]]}
            for s, ms in zip(speeds, camp, strict=True)
        ],
    }
    if not free_free:
        rot = build_rotor(rig, ne)
        report["critical_speeds_hz"] = [round(c, 4) for c in critical_speeds(rig, 4, rot)]
        report["sensitivity"] = [p.as_dict() for p in analysis.sensitivity_peaks(rig)]
        report["calibration"] = rig.calibration
    return report


def make_plots(rig, plot_dir: Path, free_free: bool, speeds: list[float], elements) -> list[str]:
    """Write the chapter-2 figures into ``plot_dir``; returns the file names."""
    # heavy, optional: matplotlib, only with --plot-dir
    from amb_plant_sim import plots

    plot_dir.mkdir(parents=True, exist_ok=True)
    ne = rig.shaft.elements if elements is None else elements
    out = []
    sp = np.linspace(0.0, max(100.0, *speeds), 41)  # the Campbell diagram needs a dense grid
    camp = analysis.campbell(
        rig, sp, free_free=free_free, elements=ne, max_frequency_hz=300.0 if free_free else 120.0
    )
    title = "Campbell diagram, " + ("free-free rotor" if free_free else "rotor with PID")
    out.append(plots.plot_campbell(sp, camp, plot_dir / "campbell.png", title))
    n_min = len(rig.stations()) - 1
    counts = list(range(n_min, max(n_min + 12, 30)))
    out.append(
        plots.plot_vs_elements(
            counts, analysis.frequencies_vs_elements(rig, counts), plot_dir / "elements.png"
        )
    )
    kp = np.linspace(0.0, 6.0e6, 121)
    out.append(
        plots.plot_vs_gain(
            kp, analysis.frequencies_vs_gain(rig, kp), rig.amb.Kz, plot_dir / "gain.png"
        )
    )
    f = np.geomspace(1.0, 1000.0, 800)
    out.append(
        plots.plot_singular_values(
            f, analysis.singular_values(rig, f), plot_dir / "singular_values.png"
        )
    )
    rot = build_rotor(rig, ne)
    marks = {
        "bearings": [b.z for b in rig.bearings],
        "sensor planes": [s.z for s in rig.sensor_planes],
    }
    ff = distinct_modes(free_free_modes(rig, 0.0, rot))
    out.append(
        plots.plot_mode_shapes(
            rot.z,
            analysis.mode_shapes(ff),
            [m.frequency_hz for m in ff[:4]],
            plot_dir / "modes_free_free.png",
            "Free-free rotor mode shapes (zero speed)",
            marks,
        )
    )
    cl = distinct_modes(closed_loop_modes(rig, 0.0, rot))
    out.append(
        plots.plot_mode_shapes(
            rot.z,
            analysis.mode_shapes(cl),
            [m.frequency_hz for m in cl[:4]],
            plot_dir / "modes_pid.png",
            "PID controlled rotor mode shapes (zero speed)",
            marks,
        )
    )
    fs = np.geomspace(1.0, 2000.0, 1500)
    out.append(
        plots.plot_sensitivity(
            fs, analysis.sensitivity(rig, fs), AXIS_NAMES, plot_dir / "sensitivity.png"
        )
    )
    return [str(p) for p in out]


def _print_text(report: dict) -> None:
    print(f"rig: {report['rig']}  model: {report['model']}  elements: {report['elements']}")
    for s in report["speeds"]:
        print(f"speed {s['speed_hz']:.2f} Hz")
        for k, m in enumerate(s["modes"], 1):
            print(
                f"  mode {k:2d}: {m['frequency_hz']:9.3f} Hz  damping {m['damping_ratio']:.4f}"
                f"  {m['whirl']}"
            )
    if "critical_speeds_hz" in report:
        print(
            "critical speeds (Hz): " + ", ".join(f"{c:.3f}" for c in report["critical_speeds_hz"])
        )
        for p in report["sensitivity"]:
            print(
                f"sensitivity {p['axis']}: peak {p['peak']:.3f} ({p['peak_db']:.2f} dB) at "
                f"{p['frequency_hz']:.1f} Hz, ISO 14839-3 zone {p['zone']}"
            )
    if "plots" in report:
        print("plots: " + ", ".join(report["plots"]))


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``amb-modal``; returns the exit status."""
    ap = argparse.ArgumentParser(
        prog="amb-modal", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--rig", type=Path, default=DEFAULT_RIG_PATH, help="rig YAML file")
    ap.add_argument("--free-free", action="store_true", help="rotor without AMBs and PID")
    ap.add_argument("--speeds-hz", type=_speeds, default=[0.0], help="e.g. 0,20,40 (Hz)")
    ap.add_argument("--elements", type=int, default=None, help="number of shaft elements")
    ap.add_argument("--modes", type=int, default=8, help="modes listed per speed")
    ap.add_argument("--json", action="store_true", help="print JSON")
    ap.add_argument("--plot-dir", type=Path, default=None, help="write PNG figures here")
    args = ap.parse_args(argv)
    try:
        rig = load_rig(args.rig)
        if args.elements is not None:
            rig = rig.with_elements(args.elements)
            build_rotor(rig)  # validates the count against the stations
        report = build_report(rig, args.free_free, args.speeds_hz, args.elements, args.modes)
        if args.plot_dir is not None:
            report["plots"] = make_plots(
                rig, args.plot_dir, args.free_free, args.speeds_hz, args.elements
            )
    except RigError as exc:
        print(f"amb-modal: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        _print_text(report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
