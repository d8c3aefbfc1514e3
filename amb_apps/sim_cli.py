r"""
``amb-sim``: the in-process closed loop (no ROS graph), a bag and ``metrics.json``.

::

    amb-sim --scenario config/scenarios/mass_loss_first_critical.yaml \
            --controller transient --w 0.75 --v 0.75 --delay 2 --out runs/ml1

composes the simulated rig, the filterbank front end and the controller pipeline in the
lock-step order of the ROS nodes (:mod:`amb_apps.closed_loop`) and writes

* ``DIR/bag``: rosbag2 (MCAP) with ``/amb/measurement``, ``/amb/wavelet/coefficients``,
  ``/amb/control/command``, ``/amb/control/status`` and ``/amb/fault/events`` (with
  ``--fault-monitor``), byte-identical to what the nodes publish;
* ``DIR/metrics.json``: :func:`amb_controller.metrics.compute_metrics` plus the
  configuration, the model source, the run time and the early action's decisions
  (``--early fe|FILE``: :mod:`amb_controller.early_action`);
* ``DIR/model.npz``: the wavelet model (identified, FE or copied), without the deliberate
  error of ``--model-gain``/``--model-phase`` (:func:`amb_controller.baselines.perturb_model`:
  the controller's model off by a gain and a 1 x phase, a robustness study on one run; the
  error is in ``metrics.json``'s ``model_error``).

Exit status 0 on success, 2 on invalid arguments or configuration.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import asdict, fields, replace
from pathlib import Path

import numpy as np

from amb_apps.closed_loop import fe_model, identify_model, run_closed_loop
from amb_apps.plant_models import early_action_model, harmonic_model, influence_by_trials
from amb_apps.report_metrics import json_default
from amb_apps.run_bag import BagRecorder
from amb_common.config_fields import default_of
from amb_common.rig import load_rig
from amb_controller.baselines import BaselineSettings, perturb_model
from amb_controller.config import (
    BASELINE_CONTROLLERS,
    CONTROLLERS,
    OUTPUT_BASES,
    ControllerConfig,
)
from amb_controller.early_model import EarlyModelBank
from amb_controller.metrics import compute_metrics, inner_summary
from amb_controller.model_file import WaveletModel
from amb_controller.pipeline import ControllerPipeline
from amb_controller.stability import own_model_radius
from amb_plant_sim.scenario import load_scenario, resolve_samples_per_rev

#: The controller's defaults (ControllerConfig's fields), the options' defaults.
DEFAULTS = {f.name: default_of(f) for f in fields(ControllerConfig)}


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``amb-sim``."""
    ap = argparse.ArgumentParser(
        prog="amb-sim",
        description="In-process closed loop: simulated rig + wavelet filterbank + wavelet "
        "controller in lock step; writes DIR/bag and DIR/metrics.json.",
    )
    ap.add_argument("--scenario", required=True, help="scenario YAML (config/scenarios/)")
    ap.add_argument(
        "--controller",
        default=DEFAULTS["controller"],
        choices=CONTROLLERS,
        help="none = PID only (default: transient, chapter 8); synchronous = adaptive "
        "influence-coefficient 1 x control, harmonic = sampled-harmonic transient control "
        "(amb_controller.baselines; --k is their convergence gain a, --w/--v the decay)",
    )
    ap.add_argument(
        "--w", type=float, default=DEFAULTS["w"], help="exponential response gain (eq. 8.6)"
    )
    ap.add_argument(
        "--v", type=float, default=DEFAULTS["v"], help="exponential decay ratio (eq. 8.6)"
    )
    ap.add_argument("--linear", type=float, default=None, help="linear decay rate per period")
    ap.add_argument(
        "--k", type=float, default=DEFAULTS["gain"], help="dimensionless gain (ch. 7 control)"
    )
    ap.add_argument(
        "--delay", type=int, default=DEFAULTS["delay_periods"], help="evaluation delay i in periods"
    )
    ap.add_argument(
        "--order",
        type=int,
        default=DEFAULTS["inverse_order"],
        help="inverse truncation order (eq. 6.35)",
    )
    ap.add_argument(
        "--horizon",
        type=int,
        default=DEFAULTS["horizon"],
        help="predictive: prediction horizon P, periods (amb_controller.predictive)",
    )
    ap.add_argument(
        "--moves", type=int, default=DEFAULTS["moves"], help="predictive: control moves C"
    )
    ap.add_argument(
        "--move-weight",
        type=float,
        default=DEFAULTS["move_weight"],
        help="predictive: dimensionless weight of the command's change per period",
    )
    ap.add_argument("--wavelet", default=DEFAULTS["wavelet"], help="PyWavelets name (orthogonal)")
    ap.add_argument(
        "--output-basis",
        default=DEFAULTS["output_basis"],
        choices=OUTPUT_BASES,
        help="control force waveform: wavelet (the thesis) or sinusoid (1 x, no harmonics)",
    )
    ap.add_argument("--samples-per-rev", type=int, default=None, help="default: scenario or 64")
    ap.add_argument(
        "--sensors",
        default=",".join(str(c) for c in DEFAULTS["sensors"]),
        help="measured sensor channels 0..7 (default inner planes: x2,y2,x3,y3)",
    )
    ap.add_argument("--force-limit", type=float, default=None, help="N per axis (default rig)")
    ap.add_argument(
        "--max-model-radius",
        type=float,
        default=DEFAULTS["max_model_radius"],
        help="largest closed-loop spectral radius on the controller's own model with which it "
        "goes ACTIVE (else the run is PID only and says why); 0 = off",
    )
    ap.add_argument("--model", default="fe", help="identify | fe | FILE (.npz)")
    ap.add_argument(
        "--model-gain",
        type=float,
        default=1.0,
        help="a deliberate model error: the controller's model scaled by this factor (> 0) at "
        "every measured quadrature pair; model.npz stays the model without it",
    )
    ap.add_argument(
        "--model-phase",
        type=float,
        default=0.0,
        help="a deliberate model error: the controller's model rotated by this many degrees at "
        "every measured quadrature pair (with --model-gain: perturb_model)",
    )
    ap.add_argument(
        "--window", type=int, default=2, help="synchronous: periods per influence update"
    )
    ap.add_argument(
        "--early",
        default=None,
        help="add the early action on a sudden unbalance: fe (the rig's FE model at the "
        "scenario's speed) | FILE (.npz of amb-early-model)",
    )
    ap.add_argument("--duration", type=float, default=None, help="override scenario duration, s")
    ap.add_argument("--seed", type=int, default=0, help="noise seed")
    ap.add_argument("--rig", default=None, help="rig YAML (default config/rig.yaml)")
    ap.add_argument("--fault-monitor", action="store_true", help="run the fault monitor core")
    ap.add_argument("--no-bag", action="store_true", help="metrics only (faster)")
    ap.add_argument("--out", required=True, help="output folder (created)")
    ap.add_argument("--progress", action="store_true", help="progress bar on stderr")
    ap.add_argument("--json", action="store_true", help="print metrics.json to stdout")
    return ap


class _Progress:
    def __init__(self, label: str, enabled: bool) -> None:
        self.label = label
        self.enabled = enabled
        self._last = -1

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        pct = int(100 * done / max(total, 1))
        if pct != self._last:
            self._last = pct
            bar = "#" * (pct // 4)
            sys.stderr.write(f"\r{self.label:>10} [{bar:<25}] {pct:3d}% ({done}/{total})")
            if done >= total:
                sys.stderr.write("\n")
            sys.stderr.flush()


def config_from_args(args, spr: int, capacity: float):
    """Return the :class:`ControllerConfig` the options ask for."""
    d = {
        "wavelet": args.wavelet,
        "samples_per_rev": spr,
        "controller": args.controller,
        "w": args.w,
        "v": args.v,
        "gain": args.k,
        "delay_periods": args.delay,
        "inverse_order": args.order,
        "horizon": args.horizon,
        "moves": args.moves,
        "move_weight": args.move_weight,
        "sensors": [int(c) for c in str(args.sensors).split(",") if c.strip()],
        "force_limit": capacity if args.force_limit is None else args.force_limit,
        "max_model_radius": args.max_model_radius or math.inf,
        "output_basis": args.output_basis,
    }
    if args.linear is not None:
        d["response"] = "linear"
        d["rate"] = args.linear
    return ControllerConfig.from_dict(d, capacity=capacity)


def radius_without_error(
    config: ControllerConfig, capacity: float, exact: WaveletModel, perturbed: WaveletModel
) -> float | None:
    """
    The spectral radius of the controller built on ``perturbed``, closed around ``exact``.

    The loop the run's plant sees if ``exact`` is the plant (the controller's own-model
    radius, ``model_radius``, does not change with a gain or phase error: the controller
    inverts its own model). None for the 1 x baselines (no realisation on this model).
    """
    if config.controller in BASELINE_CONTROLLERS:
        return None
    pipeline = ControllerPipeline(config, capacity)
    pipeline.set_model(perturbed)
    controller = pipeline.supervisor.controller
    return None if controller is None else own_model_radius(exact.markov, controller)


def run(args) -> dict:
    """Run ``amb-sim`` with parsed arguments; return the metrics written."""
    t0 = time.perf_counter()
    rig = load_rig(args.rig) if args.rig else load_rig()
    scenario = load_scenario(args.scenario, rig)
    if args.duration is not None:
        scenario = replace(scenario, duration=float(args.duration))
    spr = resolve_samples_per_rev(args.samples_per_rev, scenario)
    config = config_from_args(args, spr, rig.amb.force_limit)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    omega = 2 * np.pi * scenario.speed_hz
    model = None
    source = "none"
    baseline = None
    if config.controller in ("synchronous", "harmonic"):
        baseline = BaselineSettings(window=args.window)
        if args.model == "fe":
            model, source = harmonic_model(rig, omega, config), "fe-harmonic"
        elif args.model == "identify":
            if config.controller == "harmonic":
                raise ValueError(
                    "--model identify is available for the synchronous baseline only (trial "
                    "injections); use --model fe or a Fourier model file for harmonic"
                )
            model = influence_by_trials(rig, scenario, config, baseline, args.seed)
            source = "trial-injection"
        else:
            model, source = WaveletModel.load(args.model), str(args.model)
        model.save(out / "model.npz")
    elif config.controller != "none" or args.model == "identify":
        if args.model == "fe":
            model = fe_model(rig, omega, config)
            source = "fe"
        elif args.model == "identify":
            model = identify_model(
                rig, scenario, config, args.seed, progress=_Progress("identify", args.progress)
            )
            source = "identify"
        else:
            model = WaveletModel.load(args.model)
            source = str(args.model)
        model.save(out / "model.npz")
    error = {"gain": float(args.model_gain), "phase_deg": float(args.model_phase)}
    error_radius = None
    if error != {"gain": 1.0, "phase_deg": 0.0}:
        if model is None:
            raise ValueError("--model-gain/--model-phase need a controller with a model")
        exact = model
        model = perturb_model(model, error["gain"], math.radians(error["phase_deg"]))
        source = model.source
        error_radius = radius_without_error(config, rig.amb.force_limit, exact, model)
    early = None
    if args.early == "fe":
        early = early_action_model(rig, scenario, spr)
    elif args.early:
        early = EarlyModelBank.load(args.early)
    recorder = None
    if not args.no_bag:
        recorder = BagRecorder(out / "bag", config, rig.amb.force_limit)
    try:
        result = run_closed_loop(
            rig,
            scenario,
            config,
            model,
            args.seed,
            recorder,
            fault_monitor=args.fault_monitor,
            progress=_Progress("run", args.progress),
            baseline=baseline,
            early_model=early,
        )
    finally:
        if recorder is not None:
            recorder.close()
    metrics = compute_metrics(result, scenario.speed_hz)
    metrics.update(
        {
            "scenario": str(args.scenario),
            "scenario_name": scenario.name,
            "controller": config.to_dict(),
            "model_source": source,
            "model_error": error,
            "radius_without_model_error": error_radius,
            "seed": args.seed,
            "bag": None if recorder is None else str(out / "bag"),
            "bag_counts": None if recorder is None else dict(recorder.writer.counts),
            "wall_time": time.perf_counter() - t0,
            "model_radius": result.model_radius,
            "refused": result.refused,
            "early_detections": [asdict(d) for d in result.early_detections],
        }
    )
    if result.refused:
        print(f"amb-sim: the controller was not set ACTIVE: {result.refused}", file=sys.stderr)
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2, default=json_default))
    return metrics


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``amb-sim``."""
    args = build_parser().parse_args(argv)
    try:
        metrics = run(args)
    except (ValueError, TypeError, FileNotFoundError) as exc:
        print(f"amb-sim: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(metrics, indent=2, default=json_default))
    else:
        s = inner_summary(metrics)
        print(
            f"{metrics['scenario_name']}: controller {metrics['controller']['controller']}, "
            f"inner steady 1x {s['steady_1x'] * 1e6:.2f} um, peak after fault "
            f"{s['peak'] * 1e6:.1f} um, settling {s['settling']} rev, contacts "
            f"{metrics['contact_count']}; wrote {args.out}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
