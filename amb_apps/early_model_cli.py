"""
``amb-early-model``: write the early action's sample-domain models of the rig at its speeds.

Usage::

    amb-early-model --scenario config/scenarios/mass_loss_first_critical.yaml
        --out runs/early_model.npz [--band PCT | --speeds HZ,LO:HI:STEP,..]
        [--samples-per-rev N] [--rig config/rig.yaml]

Each model (:mod:`amb_controller.early_model`) is the FE route of
:func:`amb_apps.plant_models.early_action_model`: the rig's linearised PID loop at one constant
speed, its responses to 1 N on each bearing axis and to a sudden unit unbalance in each disk's
plane and at each AMB (a synchronous force through it, section 8.5.2). Without ``--band`` or
``--speeds`` the file holds the model at the scenario's speed;
``--band 10`` holds models from 10 % below to 10 % above it, spaced twice the early action's
``speed_tolerance`` (1 %) so that every speed of the band has one within the tolerance;
``--speeds`` lists them in Hz. Give the file to the controller
(``wavelet_controller.early_model_file``) to add the early action on a sudden unbalance
(issue 18 item 4) to its commands; it must be made for the samples per revolution the
controller runs, and the action tests nothing at a measured speed farther than
``speed_tolerance`` from all of its models.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from amb_apps.plant_models import band_speeds, early_action_bank
from amb_common.errors import RigError
from amb_common.rig import load_rig
from amb_plant_sim.errors import ScenarioError
from amb_plant_sim.scenario import load_scenario, resolve_samples_per_rev


def build_parser() -> argparse.ArgumentParser:
    """Return the parser of ``amb-early-model``."""
    ap = argparse.ArgumentParser(
        prog="amb-early-model",
        description="Write the early action's sample-domain models (FE route) at a scenario's "
        "speed or a band about it, for wavelet_controller.early_model_file.",
    )
    ap.add_argument("--scenario", required=True, help="scenario YAML (its speed is used)")
    ap.add_argument("--out", required=True, type=Path, help="model file to write (.npz)")
    speeds = ap.add_mutually_exclusive_group()
    speeds.add_argument(
        "--band", type=float, default=None,
        help="percent (0-50): models from PCT %% below to PCT %% above the scenario's speed, "
        "spaced twice the early action's speed_tolerance",
    )  # fmt: skip
    speeds.add_argument(
        "--speeds", default=None, help="comma-separated speeds in Hz, or LO:HI:STEP ranges"
    )
    ap.add_argument("--samples-per-rev", type=int, default=None, help="default: scenario or 64")
    ap.add_argument("--rig", default=None, help="rig YAML (default config/rig.yaml)")
    return ap


def parse_speeds(text: str) -> list[float]:
    """Speeds in Hz from ``"9.5,10,10.5"`` or ranges ``"9:11:0.5"`` (both ends kept)."""
    out: list[float] = []
    for part in text.split(","):
        fields = part.strip().split(":")
        try:
            values = [float(f) for f in fields]
        except ValueError:
            raise ValueError(f"speed {part!r}: expected HZ or LO:HI:STEP") from None
        if len(values) == 1:
            out.append(values[0])
        elif len(values) == 3 and values[2] > 0 and values[1] >= values[0]:
            lo, hi, step = values
            n = math.floor((hi - lo) / step + 1e-9)
            out += [lo + k * step for k in range(n + 1)]
        else:
            raise ValueError(f"speed range {part!r}: expected LO:HI:STEP with HI >= LO, STEP > 0")
    if not out or not all(math.isfinite(v) and v > 0 for v in out):
        raise ValueError(f"speeds {text!r}: expected values > 0 Hz")
    return out


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
    try:
        if args.speeds:
            speeds = parse_speeds(args.speeds)
        elif args.band is not None:
            speeds = band_speeds(scenario.speed_hz, args.band)
        else:
            speeds = [scenario.speed_hz]
    except ValueError as exc:
        print(f"amb-early-model: {exc}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()

    def progress(k: int, n: int, hz: float) -> None:
        if n > 1:
            print(f"  model {k + 1}/{n}: {hz:.4f} Hz", file=sys.stderr, flush=True)

    bank = early_action_bank(rig, scenario, spr, speeds, progress)
    path = bank.save(args.out)
    model = bank.models[0]
    hz = bank.omegas / (2 * math.pi)
    at = f"{hz[0]:.3f} Hz" if len(hz) == 1 else f"{len(hz)} speeds {hz[0]:.3f}-{hz[-1]:.3f} Hz"
    print(
        f"{path}: {at}, {spr} samples/rev, planes {', '.join(model.planes)}, "
        f"{len(model.sensors)} sensors, clearances "
        f"{' '.join(f'{c * 1e6:.0f}' for c in model.clearance)} um "
        f"({time.perf_counter() - t0:.1f} s)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
