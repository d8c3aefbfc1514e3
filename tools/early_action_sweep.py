"""
Measure the early action (issue 18 item 4) against the same controllers without it.

Usage (after ``source tools/env.sh``)::

    python tools/early_action_sweep.py phases [--monitor] [--smoothing MU] [--rows R1,R2,..]
    python tools/early_action_sweep.py robustness [--rows ..]
    python tools/early_action_sweep.py faults
    python tools/early_action_sweep.py speeds [--factors 0.9:1.1:0.005]

``phases``: the two mass-loss scenarios of ``amb-compare`` (``--quick`` durations) with the
fault at its own instant and moved to 0, 1/4, 1/2, 3/4 of its revolution (``amb-bound``'s
phases); per row the peak inner |x| after the fault (um) and its ratio to the run's own floor,
the largest inner |x| from the fault's revolution to the first sample a command can reach
(``(m_f + i) N``), which no force changes; the revolutions after the fault until the inner |x|
stays below 10 % of PID-only's steady 1 x amplitude at that phase, and the steady displacement
(1 x and the rest, ``amb-compare``'s columns) against 2 % of it (issue 18's targets).
``--monitor`` runs the fault monitor in the loop (its AUX_BEARING_CONTACT makes the controller
HOLD) and marks the runs it called a contact. ``robustness``: ``amb-compare``'s robustness
cases (model gain, phase, speed), the early action's force path perturbed as the coefficient
model (:func:`amb_apps.compare_runs.perturb_early_model`). ``faults``: every constant-speed
scenario of ``config/scenarios/faults`` with ``predictive_i1`` and ``predictive_early_i1``:
peaks, contact samples and what the early action decided. ``speeds``: ``mass_loss_1st`` with
the plant's speed moved by each factor (the fault at the same sample of the same revolution,
:func:`amb_apps.compare_cases.at_speed`), ``amb-compare``'s bank of early models (+-12 %): the
peak with and without the early action, its decision, and a count. Deterministic (seeded
noise).
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from amb_apps import compare_runs
from amb_apps.bound_cli import moved
from amb_apps.compare_cases import SPECS, Matrix
from amb_apps.compare_runs import residual_after_1x, run_metrics
from amb_common.paths import config_file
from amb_controller.early_action import EarlyActionConfig
from amb_plant_sim.scenario import load_scenario

PHASE_ROWS = "predictive_i1,predictive_early_i1,predictive_i2,predictive_early_i2,harmonic_i1"
ROBUST_ROWS = "predictive_i1,predictive_early_i1,predictive_i2,predictive_early_i2"


def _floor(result, speed_hz: float, delay: int, n: int) -> float:
    """Largest inner |x| from the fault's revolution to the first sample a command reaches."""
    kf = math.ceil(result.fault_time * speed_hz * n - 1e-9)
    k0 = (kf // n + delay) * n
    x = np.abs(result.displacement[:, [2, 3, 4, 5]]).max(axis=1)
    return float(x[(kf // n) * n : k0].max())


def _plan_note(detection) -> str:
    """The plan's largest step per sample and the smoothing that kept it within the slew."""
    return f" [step {detection.largest_step:.0f} N, mu {detection.smoothing:g}]"


def phases(matrix: Matrix, rows: list[str], monitor: bool, early_config=None) -> None:
    """Print the peak and its ratio to the run's floor per scenario, fault phase and row."""
    for key in ("mass_loss_1st", "mass_loss_2nd"):
        base = matrix.scenarios[key]
        for phase in (None, 0.0, 0.25, 0.5, 0.75):
            sc, _ = moved(base, 64, phase)
            matrix.scenarios[key] = sc
            pid = run_metrics(matrix.run(SPECS["pid"], key), sc.speed_hz)["steady_1x"]
            cells = [f"PID steady {pid * 1e6:.1f} um (2 %: {0.02 * pid * 1e6:.2f})"]
            for name in rows:
                spec = SPECS[name]
                r = matrix.run(spec, key, fault_monitor=monitor, early_config=early_config)
                m = run_metrics(r, sc.speed_hz, pid)
                peak = m["peak"]
                below = m["revs_below_10pct_pid"]
                steady = m["steady_1x"] + residual_after_1x(r)
                delay = spec.delay if spec.controller != "none" else 1
                ratio = peak / _floor(r, sc.speed_hz, delay, 64)
                kinds = [e["fault_type"] for e in r.fault_events]
                mark = " CONTACT" if "AUX_BEARING_CONTACT" in kinds else ""
                mark += "".join(_plan_note(d) for d in r.early_detections if d.acted)
                cells.append(
                    f"{name} {peak * 1e6:.1f} / {ratio:.2f}, <10 % PID "
                    f"{'never' if below is None else below} rev, steady {steady * 1e6:.2f}{mark}"
                )
            label = "own" if phase is None else f"{phase:.2f}"
            print(f"{key} {label}: " + " | ".join(cells), flush=True)
        matrix.scenarios[key] = base


def robustness(matrix: Matrix, rows: list[str]) -> None:
    """Print each row's peak under amb-compare's robustness cases."""
    Matrix.adopt(matrix)
    for name in rows:
        cells = []
        for case in compare_runs.ROBUSTNESS_CASES:
            m = compare_runs._robustness_task((matrix.args, name, case))
            cells.append(f"{case} {m['peak'] * 1e6:.1f}")
        print(f"{name}: " + " | ".join(cells), flush=True)


def faults(matrix: Matrix) -> None:
    """Print the fault suite's peaks and contacts with and without the early action."""
    for path in sorted((config_file("scenarios") / "faults").glob("*.yaml")):
        sc = load_scenario(path, matrix.rig)
        if sc.profile_hz:
            continue
        matrix.scenarios[path.stem] = sc
        holder = {}

        def keep(loop, holder=holder):
            holder["loop"] = loop
            return False

        a = matrix.run(SPECS["predictive_i1"], path.stem)
        b = matrix.run(SPECS["predictive_early_i1"], path.stem, stop=keep)
        pa, pb = (run_metrics(r, sc.speed_hz)["peak"] * 1e6 for r in (a, b))
        ca, cb = (int(r.contact.any(axis=1).sum()) for r in (a, b))
        dets = holder["loop"].pipeline.early.detections
        said = "; ".join(
            f"period {d.period} {d.plane} {d.me * 1e5:.0f} g cm "
            + ("acted" + _plan_note(d) if d.acted else
               f"stood down ({d.predicted_peak * 1e6:.0f} um, {d.clearance_share:.2f} x)")
            for d in dets
        )  # fmt: skip
        print(
            f"{path.stem}: peak {pa:.1f} -> {pb:.1f} um, contact samples {ca} -> {cb}, "
            f"early action: {said or 'nothing'}",
            flush=True,
        )


def speeds(matrix: Matrix, factors: list[float]) -> None:
    """Print the peak with and without the early action at each plant speed factor."""
    key = "mass_loss_1st"
    hz0 = matrix.scenarios[key].speed_hz
    counts = {"decided": 0, "lower": 0, "equal": 0, "higher": 0}
    ratios = []
    for f in factors:
        hz = hz0 * f
        plain = run_metrics(matrix.run(SPECS["predictive_i1"], key, speed_hz=hz), hz)["peak"]
        r = matrix.run(SPECS["predictive_early_i1"], key, speed_hz=hz)
        peak = run_metrics(r, hz)["peak"]
        counts["decided"] += bool(r.early_detections)
        diff = (peak - plain) * 1e6
        counts["equal" if abs(diff) <= 0.05 else "lower" if diff < 0 else "higher"] += 1
        ratios.append(peak / plain)
        said = ", ".join(f"{d.me * 1e5:.0f} g cm {'acted' if d.acted else 'stood down'}"
                         for d in r.early_detections)  # fmt: skip
        print(f"x {f:.3f} ({hz:.3f} Hz): {plain * 1e6:.1f} -> {peak * 1e6:.1f} um "
              f"({said or 'no decision'})", flush=True)  # fmt: skip
    print(f"{len(factors)} speeds: " + ", ".join(f"{k} {v}" for k, v in counts.items())
          + f"; peak / law alone median {np.median(ratios):.2f}")  # fmt: skip


def _factors(text: str) -> list[float]:
    lo, hi, step = (float(x) for x in text.split(":"))
    return [lo + k * step for k in range(round((hi - lo) / step) + 1)]


def main() -> None:
    """Entry point."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("what", choices=("phases", "robustness", "faults", "speeds"))
    ap.add_argument("--factors", default="0.9:1.1:0.005", help="speeds: LO:HI:STEP of the speed")
    ap.add_argument("--rows", default=None, help="comma-separated amb-compare rows")
    ap.add_argument("--monitor", action="store_true", help="phases: fault monitor in the loop")
    ap.add_argument(
        "--smoothing", type=float, default=None,
        help="phases: the early action's transient_smoothing (default: its default)",
    )  # fmt: skip
    args = ap.parse_args()
    matrix = Matrix(config_file("scenarios"), None, None, True)
    if args.what == "phases":
        cfg = None
        if args.smoothing is not None:
            cfg = EarlyActionConfig(transient_smoothing=args.smoothing)
        phases(matrix, (args.rows or PHASE_ROWS).split(","), args.monitor, cfg)
    elif args.what == "robustness":
        robustness(matrix, (args.rows or ROBUST_ROWS).split(","))
    elif args.what == "speeds":
        speeds(matrix, _factors(args.factors))
    else:
        faults(matrix)


if __name__ == "__main__":
    main()
