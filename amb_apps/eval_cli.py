"""
``amb-fault-eval``: run the fault monitor over a folder of simulated fault scenarios.

Usage::

    amb-fault-eval --scenarios config/scenarios/faults [--json] [--wavelet haar,db2,db4]
                   [--samples-per-rev 32] [--rig config/rig.yaml] [--match STR]
                   [--figures DIR] [--jobs N] [--provisional REVS]

Prints the confusion matrix (expected class per row, reported class per column; row ``NONE``
holds false alarms), detection delay (ms and revolutions), decision delay, onset-time error
and false alarms per simulated hour. The file format is in
:mod:`amb_apps.evaluation`. Several wavelets (comma-separated) simulate each
scenario once and run the monitor once per wavelet; the report (and the JSON, under
``wavelets``) then has one part per wavelet. Exit status 0 when every expected fault is
classified correctly and there is no false alarm (with every wavelet), 1 otherwise, 2 on bad
input.

``--figures DIR`` also writes PNG figures (:mod:`amb_apps.eval_figures`): one per
scenario and wavelet, ``DIR/<file stem>_<wavelet>.png`` (displacement at the four planes and
the monitor's detection ratio per level and frame around the first true onset, with the true
onsets and each event's estimated onset, detection and decision), and ``DIR/summary.png``
(detection delay and onset error of every matched case against the targets, false alarms per
hour). The paths written are printed after the tables (to stderr with ``--json``, whose
stdout stays JSON); the exit status does not depend on them.

``--provisional REVS`` has the monitor publish a provisional class that many revolutions
after each episode's estimated onset (``MonitorConfig.provisional_revs``); the report then
adds the earliest answer per expected fault (provisional or final) and how many were right
within ``FIRST_ANSWER_REVS`` revolutions of the true onset, per case (its first fault: issue
19's target) and per expected fault. The final classes and the exit status are scored as
without it.

The scenarios are simulated in ``--jobs`` parallel processes (default: the machine's cores;
:mod:`amb_apps.parallel`); the report is the same for any ``--jobs``.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from amb_apps.evaluation import FIRST_ANSWER_REVS, run_case, simulate_case, summarise
from amb_apps.parallel import add_jobs_argument, run_jobs
from amb_common.rig import load_rig


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="amb-fault-eval", description=__doc__.split("\n\n")[1])
    p.add_argument("--scenarios", required=True, help="folder of fault scenario YAML files")
    p.add_argument("--rig", default=None, help="rig file (default config/rig.yaml)")
    p.add_argument(
        "--wavelet",
        default=None,
        help="override the mother wavelet (haar, db2...); several comma-separated",
    )
    p.add_argument("--samples-per-rev", type=int, default=None, help="override (power of two)")
    p.add_argument("--match", default="", help="only files whose name contains this")
    p.add_argument("--json", action="store_true", help="print JSON instead of tables")
    p.add_argument(
        "--figures",
        default=None,
        metavar="DIR",
        help="also write PNG figures there: one per scenario and wavelet, and summary.png",
    )
    p.add_argument(
        "--provisional",
        type=float,
        default=None,
        metavar="REVS",
        help="publish a provisional class REVS revolutions after each episode's onset and "
        "score the earliest answers",
    )
    add_jobs_argument(p)
    return p


_RIGS: dict = {}


def _case_task(task: tuple) -> list:
    """
    Simulate one scenario file and run the monitor with each wavelet (in a worker process).

    ``(file, rig file or None, samples per revolution, wavelets, figure folder or None,
    provisional revolutions or None)`` ->
    ``[(CaseResult, figure path or None), ...]``, one per wavelet.

    Raises
    ------
    ValueError
        An invalid scenario, the file named in the message.
    """
    f, rig_path, spr, wavelets, fig_dir, provisional = task
    if rig_path not in _RIGS:
        _RIGS[rig_path] = load_rig(rig_path) if rig_path else load_rig()
    out = []
    try:
        case = simulate_case(f, _RIGS[rig_path], samples_per_rev=spr)
        for w in wavelets:
            trace: list | None = [] if fig_dir is not None else None
            res = run_case(case, w, trace=trace, provisional_revs=provisional)
            png = None
            if fig_dir is not None:
                from amb_apps import eval_figures  # heavy, optional: matplotlib

                png = fig_dir / f"{f.stem}_{res.wavelet}.png"
                png = eval_figures.case_figure(case, res, trace, png)
            out.append((res, png))
    except ValueError as exc:
        raise ValueError(f"{f}: {exc}") from exc
    return out


def _table(summary: dict, results: list) -> str:
    conf = summary["confusion"]
    cols = [c for c in next(iter(conf.values())) if any(conf[r][c] for r in conf)]
    w = max(len(c) for c in [*cols, *conf]) + 1
    lines = ["confusion matrix (rows: expected, columns: reported)"]
    lines.append(" " * w + "".join(c.rjust(w) for c in cols))
    for r, row in conf.items():
        if any(row.values()):
            lines.append(r.ljust(w) + "".join(str(row[c]).rjust(w) for c in cols))
    lines.append("")
    lines.append(
        f"{'class':<22}{'n':>3}{'det ms med':>12}{'det ms max':>12}{'det rev max':>12}"
        f"{'dec rev max':>12}{'onset ms med':>13}{'|onset| supp max':>17}"
    )
    for cls, d in summary["delays"].items():
        lines.append(
            f"{cls:<22}{d['n']:>3}{d['detection_ms_median']:>12.2f}{d['detection_ms_max']:>12.2f}"
            f"{d['detection_revs_max']:>12.3f}{d['decision_revs_max']:>12.2f}"
            f"{d['onset_error_ms_median']:>13.2f}{d['onset_error_abs_supports_max']:>17.1f}"
        )
    lines.append("")
    lines.append(
        f"correct {summary['correct']}/{summary['total']}, false alarms {summary['false_alarms']}"
        f" in {summary['simulated_s']:.1f} s simulated = "
        f"{summary['false_alarms_per_hour']:.1f} per hour"
    )
    first = summary["first_answers"]
    if first["provisional"]:
        lines.append(
            f"earliest answer (provisional or final) right within {FIRST_ANSWER_REVS:g} "
            f"revolutions of the onset: {first['cases_in_time']}/{first['cases']} cases (their "
            f"first fault), {first['correct_in_time']}/{first['total']} expected faults; right "
            f"at any time {first['correct']}/{first['total']}; provisional classes revised at "
            f"the decision: {first['revised']} of {first['provisional']}, false alarms "
            f"{first['false_alarms']}"
        )
    if summary.get("before_calibration"):
        lines.append(
            f"  {summary['before_calibration']} expected fault(s) before the monitor was "
            "calibrated: move the fault later in the scenario"
        )
    bad = [
        (r.name, m["expected"], m["predicted"])
        for r in results
        for m in r.matches
        if m["expected"] != m["predicted"]
    ]
    bad += [(r.name, "NONE", f["predicted"]) for r in results for f in r.false_alarms]
    for name, e, p in bad:
        lines.append(f"  {name}: expected {e}, reported {p}")
    if first["provisional"]:
        late = [
            (r.name, m["expected"], m["first_predicted"], m.get("first_decision_revs"))
            for r in results
            for m in r.matches
            if "first_predicted" in m
            and not (
                m["first_predicted"] == m["expected"]
                and m["first_decision_revs"] <= FIRST_ANSWER_REVS
            )
        ]
        for name, e, p, t in late:
            when = "" if t is None else f" after {t:.2f} rev"
            lines.append(f"  {name}: expected {e}, earliest answer {p}{when}")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``amb-fault-eval``; returns the exit status."""
    args = _parser().parse_args(argv)
    folder = Path(args.scenarios)
    files = sorted(p for p in folder.glob("*.yaml") if args.match in p.name)
    if not files:
        print(f"no *.yaml scenario files in {folder}", file=sys.stderr)
        return 2

    # loaded here first: a bad rig file is reported before any run (workers load their own)
    _RIGS[args.rig] = load_rig(args.rig) if args.rig else load_rig()
    wavelets = [w.strip() for w in args.wavelet.split(",")] if args.wavelet else [None]
    fig_dir = Path(args.figures) if args.figures else None
    if fig_dir is not None:
        try:
            fig_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            print(f"--figures {fig_dir}: {exc}", file=sys.stderr)
            return 2
        # heavy, optional: matplotlib, only with --figures
        from amb_apps import eval_figures
    written: list[Path] = []
    results: dict[str | None, list] = {w: [] for w in wavelets}
    tasks = [
        (f, args.rig, args.samples_per_rev, wavelets, fig_dir, args.provisional) for f in files
    ]

    def done(i: int, out: list) -> None:
        print(f"{files[i].name}: done ({len(out)} wavelet(s))", file=sys.stderr, flush=True)

    try:
        outs = run_jobs(_case_task, tasks, args.jobs, done if len(files) > 1 else None)
    except ValueError as exc:
        print(exc, file=sys.stderr)
        return 2
    for out in outs:
        for w, (res, png) in zip(wavelets, out, strict=True):
            results[w].append(res)
            if png is not None:
                written.append(png)
    parts = {}
    ok = True
    for w, res in results.items():
        summary = summarise(res)
        ok = ok and summary["correct"] == summary["total"] and summary["false_alarms"] == 0
        parts[w] = (summary, res)
    if args.json:
        out = {}
        for w, (summary, res) in parts.items():
            out[w] = dict(summary)
            out[w]["cases"] = [
                {
                    "name": r.name,
                    "speed_hz": r.speed_hz,
                    "wavelet": r.wavelet,
                    "samples_per_rev": r.samples_per_rev,
                    "calibration_end_sample": r.calibration_end_sample,
                    "recalibration_samples": r.recalibration_samples,
                    "matches": r.matches,
                    "false_alarms": r.false_alarms,
                    "provisional_false_alarms": r.provisional_false_alarms,
                    "events": r.events,
                    "wall_time_s": r.wall_time,
                }
                for r in res
            ]
        doc = out[wavelets[0]] if len(wavelets) == 1 else {"wavelets": out}
        print(json.dumps(doc, indent=2, default=float))
    else:
        for w, (summary, res) in parts.items():
            if len(wavelets) > 1:
                print(f"== wavelet {w}")
            print(_table(summary, res))
    if fig_dir is not None:
        # each part's own results name its wavelet (not the loop variable of the summaries)
        named = {(part[1][0].wavelet if part[1] else str(w)): part for w, part in parts.items()}
        written.append(eval_figures.summary_figure(named, fig_dir / "summary.png"))
        out = sys.stderr if args.json else sys.stdout
        print("figures written:", file=out)
        for png in written:
            print(f"  {png}", file=out)
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
