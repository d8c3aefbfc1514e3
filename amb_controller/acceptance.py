"""
Thesis acceptance runs (sections 7.4.2 and 8.5.3) on the FE plant; prints JSON.

``python -m amb_controller.acceptance [--quick]``: mass loss at the first two critical
speeds (PID only vs transient w = v = 0.75, 0.65, 0.9, linear 0.2; delay 2) and the
chapter-7 comparison at 15 Hz (proportional k = 0.21 vs moderated k = 0.34, delay 3) with
the largest acceptable gain of each (peak |x| <= 0.5 mm at every sensor after the fault,
bisection). Models: the chapter-6 FE route. Not covered yet: the (w, v) acceptability map
(figure 8.4), the linear-rate limit and the 22 Hz prediction (figures 7.2-7.5).
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace

from amb_controller.closed_loop import fe_model, run_closed_loop
from amb_controller.metrics import compute_metrics, inner_summary
from amb_controller.pipeline import ControllerConfig
from amb_tools.paths import config_file

LIMIT = 0.5e-3  # m, the thesis's acceptability bound (sections 7.4.2, 8.5.1)


def _run(rig, scenario, cfg, model):
    metrics = compute_metrics(run_closed_loop(rig, scenario, cfg, model), scenario.speed_hz)
    summary = inner_summary(metrics)
    summary["peak_any"] = max(s["peak_after_fault"] for s in metrics["sensors"].values())
    summary["contacts"] = metrics["contact_count"]
    return summary


def mass_loss(rig, name: str) -> dict:
    """PID only and the transient controller variants of section 8.5.3."""
    from amb_plant_sim.scenario import load_scenario

    scenario = load_scenario(config_file(f"scenarios/{name}.yaml"), rig)
    cfg = ControllerConfig(samples_per_rev=64, delay_periods=2)
    model = fe_model(rig, 2 * math.pi * scenario.speed_hz, cfg)
    out = {
        "speed_hz": scenario.speed_hz,
        "pid": _run(rig, scenario, replace(cfg, controller="none"), model),
    }
    for label, kw in (
        ("w=v=0.75", {"w": 0.75, "v": 0.75}),
        ("w=v=0.65", {"w": 0.65, "v": 0.65}),
        ("w=v=0.9", {"w": 0.9, "v": 0.9}),
        ("linear 0.2", {"response": "linear", "rate": 0.2}),
    ):
        out[label] = _run(rig, scenario, replace(cfg, **kw), model)
    return out


def chapter7(rig, quick: bool) -> dict:
    """Proportional vs moderated at 15 Hz, 196 g cm, delay 3; largest acceptable gains."""
    from amb_plant_sim.scenario import load_scenario

    scenario = load_scenario(config_file("scenarios/mass_loss_196gcm_15Hz.yaml"), rig)
    cfg = ControllerConfig(samples_per_rev=64, delay_periods=3, inverse_order=5)
    model = fe_model(rig, 2 * math.pi * scenario.speed_hz, cfg)
    out = {"pid": _run(rig, scenario, replace(cfg, controller="none"), model)}
    for name, k in (("proportional", 0.21), ("moderated", 0.34)):
        c = replace(cfg, controller=name, gain=k)
        out[f"{name} k={k}"] = _run(rig, scenario, c, model)
        lo, hi = 0.0, 4.0
        for _ in range(4 if quick else 7):
            mid = 0.5 * (lo + hi)
            r = _run(rig, scenario, replace(c, gain=mid), model)
            ok = r["peak_any"] <= LIMIT and r["steady_1x"] <= out["pid"]["steady_1x"]
            lo, hi = (mid, hi) if ok else (lo, mid)
        out[f"{name} acceptable k max"] = lo
    return out


def main(argv=None) -> int:
    """Print the acceptance numbers as JSON."""
    from amb_plant_sim.rig import load_rig

    ap = argparse.ArgumentParser(prog="python -m amb_controller.acceptance")
    ap.add_argument("--quick", action="store_true", help="fewer bisection steps")
    args = ap.parse_args(argv)
    rig = load_rig()
    result = {
        "mass_loss_first_critical": mass_loss(rig, "mass_loss_first_critical"),
        "mass_loss_second_critical": mass_loss(rig, "mass_loss_second_critical"),
        "chapter7_15Hz": chapter7(rig, args.quick),
    }
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
