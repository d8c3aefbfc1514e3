"""
Sweep the predictive controller's settings on ``amb-compare``'s scenarios (in process, no DDS).

::

    python tools/predictive_sweep.py --scenarios mass_loss_1st,contact_case2
        --settings 20:3:0.25:0.03:1,20:3:0:0:2 [--full]

Each setting is ``horizon:moves:move_weight:input_weight:delay``
(:mod:`amb_controller.predictive`); each row prints the own-model radius, the peak inner
displacement after the fault, the revolutions until it stays below 10 % of PID only's steady
amplitude, the steady 1 x amplitude, the peak force and the contact onsets, with
``amb-compare``'s metrics and models (FE route, sinusoidal force, Haar x_{1,1}, lock step).
``--quick`` scenario durations unless ``--full``. How the defaults were chosen from such a
sweep: docs/controller_notes.md, "Predictive controller".
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

from amb_apps.closed_loop import run_closed_loop
from amb_apps.compare_cases import SCENARIOS, SPECS, Matrix, Spec
from amb_apps.compare_runs import run_metrics
from amb_plant_sim.scenario import load_scenario


def _setting(text: str) -> tuple[int, int, float, float, int]:
    parts = text.split(":")
    if len(parts) != 5:
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected horizon:moves:move_weight:input_weight:delay"
        )
    return int(parts[0]), int(parts[1]), float(parts[2]), float(parts[3]), int(parts[4])


def main() -> None:
    """Run the sweep and print one line per scenario and setting."""
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument(
        "--scenarios",
        default=",".join(SCENARIOS),
        help="amb-compare scenario keys, or scenario files of config/scenarios",
    )
    ap.add_argument(
        "--settings",
        type=lambda s: [_setting(t) for t in s.split(",")],
        default=[(20, 3, 0.25, 0.03, 1), (20, 3, 0.25, 0.03, 2)],
        help="comma-separated horizon:moves:move_weight:input_weight:delay",
    )
    ap.add_argument("--full", action="store_true", help="the scenarios' full durations")
    ap.add_argument(
        "--input-noise",
        type=float,
        default=None,
        help="run the input-disturbance experiment (tools/predictive_input_disturbance.py) "
        "with this dimensionless measurement noise instead of the shipped law",
    )
    args = ap.parse_args()
    if args.input_noise is not None:
        from predictive_input_disturbance import InputDisturbanceController

        import amb_controller.pipeline as pipeline

        def build(markov, delay, horizon, moves, move_w, input_w):
            return InputDisturbanceController(
                markov, delay, horizon, moves, move_w, input_w, args.input_noise
            )

        pipeline.PredictiveController = build
    matrix = Matrix(Path("config/scenarios"), None, None, not args.full)
    for key in args.scenarios.split(","):
        scenario = matrix.scenarios.get(key)
        if scenario is None:  # a scenario file of config/scenarios, its full duration
            scenario = load_scenario(Path("config/scenarios") / key, matrix.rig)
        pid_config = matrix.config(SPECS["pid"], scenario)
        pid = run_metrics(
            run_closed_loop(matrix.rig, scenario, pid_config, None), scenario.speed_hz
        )
        print(
            f"{key}: PID only peak {pid['peak'] * 1e6:.1f} um, steady 1 x "
            f"{pid['steady_1x'] * 1e6:.2f} um, {pid['contacts']} contact onsets",
            flush=True,
        )
        for horizon, moves, move_w, input_w, delay in args.settings:
            spec = Spec("predictive", "predictive", delay, "fe", "sinusoid")
            config = replace(
                matrix.config(spec, scenario),
                horizon=horizon,
                moves=moves,
                move_weight=move_w,
                input_weight=input_w,
            )
            t0 = time.perf_counter()
            result = run_closed_loop(
                matrix.rig, scenario, config, matrix.model(spec, scenario, config)
            )
            m = run_metrics(result, scenario.speed_hz, pid["steady_1x"])
            radius = "-" if result.model_radius is None else f"{result.model_radius:.3f}"
            print(
                f"  P={horizon} C={moves} move_w={move_w:g} input_w={input_w:g} i={delay}: "
                f"radius {radius}{' REFUSED' if result.refused else ''}, peak "
                f"{m['peak'] * 1e6:.1f} um, below 10 % PID after {m['revs_below_10pct_pid']} rev, "
                f"steady {m['steady_1x'] * 1e6:.2f} um, force {m['peak_force']:.0f} N, "
                f"{m['contacts']} contacts ({time.perf_counter() - t0:.0f} s)",
                flush=True,
            )


if __name__ == "__main__":
    main()
