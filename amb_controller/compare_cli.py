"""
``amb-compare``: controllers x scenarios on the simulated rig, one table, figures.

::

    amb-compare --out runs/compare [--robustness] [--quick]

Controllers (all at the same per-axis force limit, the rig's bearing capacity unless
``--force-limit``; the wavelet ones on the Haar x_{1,1} coefficients of the inner sensors):

* ``pid``: PID only (no added force);
* ``wavelet_i1`` / ``wavelet_i2``: the chapter-8 transient controller (eq. 8.10), w = v =
  0.75, 5th-order inverse of the FE-route model, delay i = 1 and the thesis's i = 2;
* ``harmonic_i1``: sampled-harmonic transient control (Keogh et al. 2002), same w, v, order;
* ``synchronous_i1``: adaptive influence-coefficient control (Burrows & Sahinkaya 1983,
  Knospe et al. 1995), T identified by trial injections, gain a = 0.5, 2-period window.

Scenarios: 430 g cm mass loss at the model's first and second critical speeds, 150 N step
synchronous force at the third, and the figure-5.27 case-2 mass loss that leads to contacts
(19 Hz; with ``wavelet_reconf``: transient controller OFF until the fault monitor reports
MASS_LOSS, HOLD on AUX_BEARING_CONTACT, section 3.3.2).

Metrics: :mod:`amb_controller.compare_runs`. Cases: :mod:`amb_controller.compare_cases`;
runs: :mod:`amb_controller.compare_runs`; report: :mod:`amb_controller.compare_report`.

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
at the monitor's *alarm* (confirmed detection, the onset revolution). Measured (64
samples/rev, i = 1): onset 2.000 s (revolution 38), first contact 2.036 s (0.7 revolution
later, simulator truth), alarm within revolution 38, the MASS_LOSS and AUX_BEARING_CONTACT
events both at the decision ~10 revolutions later. Engaged at the decision the controller is
set ACTIVE and at once HOLD by the contact event with a zero last command: the run equals
PID (773 um, 20 contact onsets; with the earlier monitor, which reported no contact event,
835 um and 54). Engaged at the alarm the first force can act in revolution 40 (i = 1), after
the first contact; HOLD at the contact event then repeats a stale non-zero command: 793 um,
28 onsets. The start-up of eq. 8.10 is not the cause: from a zero state its first output is
``(1/w - 1) B^(0) q`` (1/3 of the full correction for w = 0.75) and no command saturated
(peak 491-577 N, limit 1000 N). Controllers running before the fault (``wavelet_i1``,
``harmonic_i1``) avoid every contact (285 / 268 um) because they had already removed the
211 um of 1 x vibration of the pre-fault unbalance: in case 2 the margin comes from running
before the fault, not from reconfiguration. ``wavelet_reconf_alarm_ramp`` is
``wavelet_reconf_alarm`` with HOLD ramping the held command to zero over
``HOLD_RAMP_PERIODS`` = 4 periods (:mod:`amb_controller.supervisor`, "Hold-last or
ramp-to-zero"): measured (full 5 s run) 780.8 um, 18 contact onsets, RMS force 69.2 N,
against hold-last 793.3 um, 28 onsets, 198.8 N, and PID only 773.3 um, 20 onsets (``--quick``:
same peaks and onsets): the stale held force adds contacts, the ramp removes them (fewer than
PID; the peak stays at the PID level, reached before the controller could act). In the full
run ``wavelet_i2`` (i = 2) diverges in case 2 (12.0 mm, 81 onsets) although the radius on its
own FE model is 0.928: the contacts and the force limit are outside that model.

Target on the mass-loss cases: measured (64 samples/rev, i = 1, w = v = 0.75, FE-route models)
----------------------------------------------------------------------------------------------
The report's "Target" section is written from each run's numbers (:func:`verdict`). At the
first / second critical speed ``wavelet_i1`` beats ``synchronous_i1`` on peak (94.7 vs
111.4 um, 197.8 vs 210.2 um) and loses to ``harmonic_i1`` (91.1, 188.9 um: by 3.9 % and
4.7 %). The force limit (1000 N) decides nothing: peak forces 43 / 39 / 40 N (first) and
186 / 167 / 173 N (second). Why ``wavelet_i1`` never reaches 10 % on displacement, checked:

* its 1 x vibration does settle: ``revs_to_10_1x`` 12 and 12 revolutions (harmonic 10 and
  10, synchronous 9 and 14);
* what stays is harmonics: over the last 10 revolutions (6 s runs; ``harmonics_um``) the
  inner sensors carry 3 x 6.6 um, 5 x 2.2 um, 7 x 2.5 um (first critical; second: 17.0,
  11.6, 2.0 um) against 0.16, 0.09, 0.11 um under PID and under both baselines: the odd
  harmonics of the Haar square-wave force, > 10 % of the peak (11.3 um tail peak vs 9.5
  um; 31.3 vs 19.8 um);
* of the 3.6 um peak gap to ``harmonic_i1`` at the first critical speed, 1.6 um is 1 x
  (peak 1 x amplitude 87.0 vs 85.4 um), the rest harmonics at the peak revolution. The 1 x
  part is the model inverse: ``||B^(0) G^(0) - I||`` is 0.58 for the Haar model and 0.39 for
  the Fourier one (0.53 vs 0.18 at the second critical), and the exact closed-loop radius
  on the own FE model is 0.798 vs 0.783 (0.820 vs 0.820; ideal 0.667);
* db2 / db4 instead of Haar are no remedy here: the exact closed-loop radius on their own
  FE models is 0.991 and 1.000 (a pole at or next to z = 1: integral action that hardly
  acts), and in
  the run db2 leaves 107 um of steady 1 x (peak 135.6 um), db4 commands 0.02 N (its first
  periods are not settled, and then the loop does nothing: peak 141.5 um = PID).
  A higher inverse order (10 instead of 5) leaves the Haar radius at 0.800 (0.816).

No sound change inside this module's lane (baselines, comparison, multi-level, supervisor)
was found that beats both baselines: the cure is a control waveform without harmonics (a
sinusoidal 1 x synthesis, :mod:`amb_controller.basis`, not in this lane) or the multi-level
controller (``--multilevel``: reaches 10 % in 12 revolutions, at a higher peak, module
notes below).

Third critical speed (``sync_150N_3rd``): ``wavelet_i1_8sensors`` is ``wavelet_i1`` measuring
all 8 sensors (least-squares inverse). With the 4 inner sensors the steady-state gain
``G(1)`` is nearly singular there (singular values down to 0.0035 of the largest) and the
5th-order inverse poor (``||B G - I|| = 0.69`` at k = 0): the exact closed loop on the FE
Markov model has spectral radius 1.027, so the divergence of every inner-sensor controller
is predicted by the (correct) model; with all 8 sensors ``B G = I`` and the radius is 0.74-0.78.

Also written: figure 8.3 redrawn for i = 1..4 (``fig8_3_stability_i1-4.png``), and the time
for one command (controller step + synthesis + limit) against the period (``timing``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from amb_controller.compare_cases import Matrix
from amb_controller.compare_report import figures, markdown
from amb_controller.compare_runs import command_timing, comparison, robustness


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
    ap.add_argument("--quiet", action="store_true", help="no progress on stderr")
    return ap


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``amb-compare``; exit 0, or 2 on invalid arguments."""
    args = build_parser().parse_args(argv)
    from amb_tools.paths import config_file

    scenario_dir = args.scenario_dir or config_file("scenarios")

    def progress(text: str) -> None:
        if not args.quiet:
            print(text, file=sys.stderr, flush=True)

    try:
        matrix = Matrix(scenario_dir, args.samples_per_rev, args.force_limit, args.quick)
        t0 = time.perf_counter()
        result = comparison(matrix, progress=progress, multilevel=args.multilevel)
        if args.robustness:
            result["robustness"] = robustness(matrix, progress)
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
