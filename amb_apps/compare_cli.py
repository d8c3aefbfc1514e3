"""
``amb-compare``: controllers x scenarios on the simulated rig, one table, figures.

::

    amb-compare --out runs/compare [--robustness] [--quick] [--jobs N]

Controllers (all at the same per-axis force limit, the rig's bearing capacity unless
``--force-limit``; the wavelet ones on the Haar x_{1,1} coefficients of the inner sensors):

* ``pid``: PID only (no added force);
* ``wavelet_i1`` / ``wavelet_i2``: the chapter-8 transient controller (eq. 8.10), w = v =
  0.75, 5th-order inverse of the FE-route model, delay i = 1 and the thesis's i = 2;
* ``wavelet_sin_i1`` / ``wavelet_sin_i2``: the same law on the same Haar coefficients with a
  1 x sinusoidal force instead of the Haar square wave (``output_basis = "sinusoid"``, its
  FE-route model from sinusoidal inputs to Haar coefficients): no 3 x, 5 x, 7 x force;
* ``predictive_i1`` / ``predictive_i2``: the receding-horizon controller on the same Haar
  coefficients and FE-route model with a 1 x sinusoidal force (issue 18 item 2,
  :mod:`amb_controller.predictive`) with ``ControllerConfig``'s default horizon, moves and
  weights;
* ``predictive_early_i1`` / ``predictive_early_i2``: the same with the early action on a
  sudden unbalance (issue 18 item 4, :mod:`amb_controller.early_action`, its FE-route
  sample-domain model at the scenario's speed);
* ``harmonic_i1`` / ``harmonic_i2``: sampled-harmonic transient control (Keogh et al. 2002),
  same w, v, order;
* ``synchronous_i1`` / ``synchronous_i2``: adaptive influence-coefficient control (Burrows &
  Sahinkaya 1983, Knospe et al. 1995), T identified by trial injections, gain a = 0.5, 2-period
  window (the baselines at both delays: every row is compared with those at its own);
* ``limit_i1`` / ``limit_i2``: not a controller but the best response any controller with
  that delay could give (``amb-bound``, :mod:`amb_plant_sim.control_limit`); every row's
  ``peak_to_limit`` is its peak over the limit at its own delay (``--no-limit``: skipped).

Scenarios: 430 g cm mass loss at the model's first and second critical speeds, 150 N step
synchronous force through AMB 1 at the first, second and third (section 8.5.2; the step 3 s
into the run at the first two, after the controllers and the early action's reference have
settled), and the figure-5.27 case-2 mass loss that leads to contacts
(19 Hz; with ``wavelet_reconf``: transient controller OFF until the fault monitor reports
MASS_LOSS, HOLD on AUX_BEARING_CONTACT, section 3.3.2).

The cases are in :mod:`amb_apps.compare_cases`, the runs and the metrics of each (their
definitions) in :mod:`amb_apps.compare_runs`, the report in
:mod:`amb_apps.compare_report`.

Multi-level (``--multilevel``, issue 9): on the two mass-loss scenarios, levels 1 x, 2 x and
4 x (thesis p = 1, 2, 3) controlled at once, w = v = 0.75 per level, i = 1:
``wavelet_124_coupled`` (one eq.-8.10 controller on the coupled model of all three levels)
and ``wavelet_124_perlevel`` (:class:`~amb_controller.multilevel.MultiLevelController`: one
controller per level on the level's own model, forces summed before the limiter); compare
with ``wavelet_i1`` (1 x only). ``residual_um`` is the peak inner displacement of the last 10
revolutions left after removing its 1 x fit (the harmonics a 1 x Haar square wave adds).

Reconfiguration variants on ``contact_case2``: ``wavelet_reconf`` engages on the fault
monitor's MASS_LOSS *event* (emitted at its decision, ~10 revolutions after the onset; the
event's detection_sample_index is the early detection); ``wavelet_reconf_alarm`` engages
at the monitor's *alarm* (confirmed detection, the onset revolution);
``wavelet_reconf_alarm_ramp`` is ``wavelet_reconf_alarm`` with HOLD ramping the held command
to zero over ``HOLD_RAMP_PERIODS`` = 4 periods (:mod:`amb_controller.supervisor`, "Hold-last
or ramp-to-zero"). The current numbers: docs/results.md#compare (``make results
SECTIONS=compare``); what past runs measured and concluded: ``docs/controller_notes.md``.

The report's "Target" section is written from each run's numbers (:func:`verdict`).

Third critical speed (``sync_150N_3rd``): ``wavelet_i1_8sensors`` is ``wavelet_i1`` measuring
all 8 sensors (least-squares inverse): with the 4 inner sensors the steady-state gain ``G(1)``
is nearly singular at that speed.

Also written: figure 8.3 redrawn for i = 1..4 (``fig8_3_stability_i1-4.png``), and the time
for one command (controller step + synthesis + limit) against the period (``timing``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from amb_apps.compare_cases import Matrix
from amb_apps.compare_report import figures, markdown
from amb_apps.compare_runs import command_timing, comparison, robustness
from amb_apps.parallel import add_jobs_argument
from amb_common.paths import config_file


def build_parser() -> argparse.ArgumentParser:
    """Return the parser of ``amb-compare``."""
    ap = argparse.ArgumentParser(
        prog="amb-compare",
        description="Controllers x scenarios on the simulated rig: table (markdown, JSON) "
        "and figures.",
    )
    ap.add_argument("--out", required=True, type=Path, help="output folder (created)")
    ap.add_argument("--scenario-dir", type=Path, default=None, help="default config/scenarios")
    ap.add_argument("--samples-per-rev", type=int, default=None, help="default: per scenario")
    ap.add_argument("--force-limit", type=float, default=None, help="N per axis (default rig)")
    ap.add_argument("--robustness", action="store_true", help="add the robustness matrix")
    ap.add_argument(
        "--quick", action="store_true", help="scenarios cut to 4 s, or 2 s after a later fault"
    )
    ap.add_argument(
        "--multilevel", action="store_true", help="add 1x+2x+4x coupled and per-level rows"
    )
    ap.add_argument(
        "--no-limit", action="store_true", help="skip the limit_i1 / limit_i2 rows (amb-bound)"
    )
    add_jobs_argument(ap)
    ap.add_argument("--quiet", action="store_true", help="no progress on stderr")
    return ap


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``amb-compare``; exit 0, or 2 on invalid arguments."""
    args = build_parser().parse_args(argv)

    scenario_dir = args.scenario_dir or config_file("scenarios")

    def progress(text: str) -> None:
        if not args.quiet:
            print(text, file=sys.stderr, flush=True)

    try:
        matrix = Matrix(scenario_dir, args.samples_per_rev, args.force_limit, args.quick)
        t0 = time.perf_counter()
        result = comparison(
            matrix,
            progress=progress,
            multilevel=args.multilevel,
            limits=not args.no_limit,
            jobs=args.jobs,
        )
        if args.robustness:
            result["robustness"] = robustness(matrix, progress, args.jobs)
    except (ValueError, TypeError, FileNotFoundError) as exc:
        print(f"amb-compare: {exc}", file=sys.stderr)
        return 2
    timing = command_timing(force_limit=matrix.rig.amb.force_limit)
    args.out.mkdir(parents=True, exist_ok=True)
    speeds = {k: s.speed_hz for k, s in matrix.scenarios.items()}
    paths = figures(result, args.out)
    doc = {
        "speeds_hz": speeds,
        "force_limit": matrix.force_limit,
        "table": result["table"],
        "limits_unavailable": result["limits_unavailable"],
        "robustness": result.get("robustness"),
        "timing": timing,
        "wall_time": time.perf_counter() - t0,
        "figures": [p.name for p in paths],
    }
    (args.out / "comparison.json").write_text(json.dumps(doc, indent=2))
    (args.out / "comparison.md").write_text(markdown(result, timing, speeds, matrix.force_limit))
    print(f"amb-compare: wrote {args.out / 'comparison.md'} and {len(paths)} figures")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
