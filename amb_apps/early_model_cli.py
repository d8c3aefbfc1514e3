"""
``amb-early-model``: write the early action's sample-domain model of the rig at a speed.

Usage::

    amb-early-model --scenario config/scenarios/mass_loss_first_critical.yaml
        --out runs/early_model.npz [--samples-per-rev N] [--rig config/rig.yaml]

The model (:mod:`amb_controller.early_model`) is the FE route of
:func:`amb_apps.plant_models.early_action_model`: the rig's linearised PID loop at the
scenario's constant speed, its responses to 1 N on each bearing axis and to a sudden unit
unbalance in each disk's plane. Give the file to the controller
(``wavelet_controller.early_model_file``) to add the early action on a sudden unbalance
(issue 18 item 4) to its commands; it must be made for the samples per revolution the
controller runs and for the speed the rig runs at (the action stands down off that speed:
its test finds no unbalance that fits).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from amb_apps.plant_models import early_action_model
from amb_common.errors import RigError
from amb_common.rig import load_rig
from amb_plant_sim.errors import ScenarioError
from amb_plant_sim.scenario import load_scenario, resolve_samples_per_rev


def build_parser() -> argparse.ArgumentParser:
    """Return the parser of ``amb-early-model``."""
    ap = argparse.ArgumentParser(
        prog="amb-early-model",
        description="Write the early action's sample-domain model (FE route) at a scenario's "
        "speed, for wavelet_controller.early_model_file.",
    )
    ap.add_argument("--scenario", required=True, help="scenario YAML (its speed is used)")
    ap.add_argument("--out", required=True, type=Path, help="model file to write (.npz)")
    ap.add_argument("--samples-per-rev", type=int, default=None, help="default: scenario or 64")
    ap.add_argument("--rig", default=None, help="rig YAML (default config/rig.yaml)")
    return ap


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (2 on bad input)."""
    args = build_parser().parse_args(argv)
    try:
        rig = load_rig(args.rig)
        scenario = load_scenario(args.scenario, rig)
    except (RigError, ScenarioError, OSError) as exc:
        print(f"amb-early-model: {exc}", file=sys.stderr)
        return 2
    if scenario.speed_hz is None or scenario.profile_hz:
        print(
            f"amb-early-model: scenario {scenario.name} has no constant speed; the model is "
            "made at one speed",
            file=sys.stderr,
        )
        return 2
    if not args.out.parent.is_dir():
        print(f"amb-early-model: folder {args.out.parent} does not exist", file=sys.stderr)
        return 2
    spr = resolve_samples_per_rev(args.samples_per_rev, scenario)
    t0 = time.perf_counter()
    model = early_action_model(rig, scenario, spr)
    path = model.save(args.out)
    print(
        f"{path}: {scenario.speed_hz:.3f} Hz, {spr} samples/rev, planes {', '.join(model.planes)}, "
        f"{len(model.sensors)} sensors, clearance {model.clearance * 1e6:.0f} um "
        f"({time.perf_counter() - t0:.1f} s)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
