r"""``amb-report``: thesis-style figures and ``metrics.json`` from any bag of this project.

::

    amb-report runs/pid/bag runs/wavelet/bag --labels "PID only,PID + wavelet" \
               --scenario config/scenarios/mass_loss_first_critical.yaml --out report/

reads one or more rosbag2 folders with the ``/amb/*`` topics (``amb-sim``, ``amb-run``'s
recorder or ``ros2 bag record``; missing topics are tolerated and listed; a bag of a system run in
a namespace, ``/rig1/amb/*``, is read under the one namespace it holds the streams in, or the one
``--namespace`` names) and writes to ``DIR``:

* ``displacement.png`` (fig. 8.11), ``coefficients_1x.png`` (figs. 8.11 (e-h), 7.3),
  ``forces.png`` (fig. 8.12), ``orbits.png`` (fig. 5.27), ``fault_timeline.png`` and
  ``levels_<label>.png`` per bag (figs. 5.1-5.18);
* ``<label>/metrics.json`` per bag (:mod:`amb_apps.report_metrics`: the functions and keys of
  ``amb-sim``'s ``metrics.json``), ``comparison.md`` (key metrics side by side) and
  ``report.md`` (links to everything, what was missing).

With ``--json`` the metrics of every bag are printed to stdout (a mapping label -> metrics).
Exit status 0 on success, 2 on invalid arguments or an unreadable bag.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

from amb_apps.report_metrics import (
    bag_metrics,
    choose_fault_time,
    inner_summary,
    json_default,
    scenario_fault,
)
from amb_controller.metrics import revolutions_below
from amb_tools.bag_read import read_bag


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``amb-report``."""
    ap = argparse.ArgumentParser(
        prog="amb-report",
        description="Thesis-style figures (PNG), metrics.json per bag, comparison.md and "
        "report.md from rosbag2 folders of the /amb/* topics.",
    )
    ap.add_argument("bags", nargs="+", metavar="BAG", help="rosbag2 folder(s)")
    ap.add_argument("--out", required=True, help="output folder (created)")
    ap.add_argument(
        "--labels",
        default=None,
        help='comma-separated labels, one per bag (e.g. "PID only,PID + wavelet"); '
        "default: the bag folder names",
    )
    ap.add_argument(
        "--scenario",
        default=None,
        help="scenario YAML the bags ran: fault time and running speed as amb-sim uses them",
    )
    ap.add_argument(
        "--fault-time",
        type=float,
        default=None,
        help="s, fault time for the 'after the fault' metrics (overrides scenario and FaultEvents)",
    )
    ap.add_argument(
        "--namespace",
        default=None,
        help="namespace the system ran in (/rig1: /rig1/amb/measurement, ...); default: the one "
        "each bag holds the streams under",
    )
    ap.add_argument("--json", action="store_true", help="print the metrics as JSON to stdout")
    return ap


def default_label(bag: Path) -> str:
    """Return a label for a bag folder: its name, or its parent's for a folder named ``bag``."""
    bag = bag.resolve()
    return bag.parent.name if bag.name == "bag" and bag.parent.name else bag.name


def slug(label: str, taken: set[str]) -> str:
    """Return a file-name-safe, unique version of ``label``."""
    base = re.sub(r"[^A-Za-z0-9._-]+", "_", label).strip("_") or "bag"
    name, i = base, 2
    while name in taken:
        name, i = f"{base}_{i}", i + 1
    taken.add(name)
    return name


def _fmt(value, scale: float = 1.0, digits: int = 1) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, int) and scale == 1.0:
        return str(value)
    return f"{value * scale:.{digits}f}"


def comparison_table(labels: list[str], metrics: list[dict]) -> str:
    """Return ``comparison.md``: the key metrics of each bag side by side (Markdown).

    Rows: steady 1 x amplitude and peak after the fault at the inner sensors (µm), revolutions
    to settle (largest over the inner sensors), peak wavelet and total force per bearing (N);
    with two bags a last column gives the ratio second / first.
    """
    inner = ("x2", "y2", "x3", "y3")
    rows: list[tuple[str, list]] = []
    for name in inner:
        rows.append(
            (
                f"steady 1 x amplitude at {name} (µm)",
                [_get(m, "sensors", name, "steady_1x_amplitude") for m in metrics],
            )
        )
    for name in inner:
        rows.append(
            (
                f"peak after the fault at {name} (µm)",
                [_get(m, "sensors", name, "peak_after_fault") for m in metrics],
            )
        )
    rows.append(
        (
            "revolutions to settle (largest at x2, y2, x3, y3)",
            [inner_summary(m)["settling"] for m in metrics],
        )
    )
    if any(m.get("revs_below_10pct_pid") is not None for m in metrics):
        rows.append(
            (
                "revolutions until below 10 % of PID only's steady 1 x (inner peak)",
                [m.get("revs_below_10pct_pid") for m in metrics],
            )
        )
    for b in ("1", "2"):
        rows.append(
            (
                f"peak wavelet force, bearing {b} (N)",
                [_get(m, "bearings", b, "peak_wavelet_force") for m in metrics],
            )
        )
    for b in ("1", "2"):
        rows.append(
            (
                f"peak total control force, bearing {b} (N)",
                [_get(m, "bearings", b, "peak_total_force") for m in metrics],
            )
        )
    two = len(metrics) == 2
    head = "| metric | " + " | ".join(labels) + (f" | {labels[1]} / {labels[0]} |" if two else " |")
    sep = "|---|" + "---:|" * (len(labels) + (1 if two else 0))
    lines = [
        "# Key metrics side by side",
        "",
        "Fault time per bag: "
        + "; ".join(
            f"{lab}: {m['fault_time']:.4g} s ({m['fault_time_source']})"
            for lab, m in zip(labels, metrics, strict=True)
        )
        + ". Definitions: `amb_controller/metrics.py` (steady 1 x over the last 10 "
        "revolutions; settling = revolutions after the fault period until the 1 x wavelet "
        "phasor stays in a 5 % band of its largest excursion; forces = largest hypot(f_x, f_y)).",
        "",
        head,
        sep,
    ]
    for name, vals in rows:
        is_um = "(µm)" in name
        scale = 1e6 if is_um else 1.0
        cells = [_fmt(v, scale, 1) for v in vals]
        if name.startswith("revolutions until below"):
            cells = ["not reached" if v is None else str(v) for v in vals]
        if two:
            a, b = vals
            cells.append("n/a" if a in (None, 0) or b is None else f"{b / a:.3f}")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def add_below_pid(metrics: list[dict]) -> None:
    """
    Add ``revs_below_10pct_pid`` to every bag's metrics, when one bag is PID only.

    The revolutions after the fault period until the inner sensors' per-revolution peak stays
    below 10 % of the PID-only bag's steady 1 x amplitude (largest of x2, y2, x3, y3;
    :func:`amb_controller.metrics.revolutions_below`); ``None``: not within the run. Without
    exactly one PID-only bag (``controller`` ``none``), or without the measurements, the
    field is ``None`` and ``revs_below_10pct_pid_source`` says why.
    """
    pid = [m for m in metrics if (m.get("controller") or {}).get("controller") == "none"]
    why, steady = "", None
    if len(pid) != 1:
        why = f"{len(pid)} PID-only bags (controller none) among the bags; needs exactly one"
    elif (steady := inner_summary(pid[0])["steady_1x"]) is None:
        why = "the PID-only bag has no measurements"
    for m in metrics:
        peaks = m.get("inner_revolution_peaks")
        if why or peaks is None:
            m["revs_below_10pct_pid"] = None
            m["revs_below_10pct_pid_source"] = why or "no measurements in this bag"
            continue
        level = 0.1 * steady
        m["revs_below_10pct_pid"] = revolutions_below(peaks, level)
        m["revs_below_10pct_pid_source"] = (
            f"inner peak per revolution below 10 % of PID only's steady 1 x ({level * 1e6:.2f} um)"
        )


def _get(m: dict, *keys):
    for k in keys:
        if m is None:
            return None
        m = m.get(k)
    return m


def report_markdown(runs, figures, metrics_paths, metrics) -> str:
    """Return ``report.md``: bags, fault times, figures (linked) and what was missing."""
    lines = [
        "# amb-report",
        "",
        "## Bags",
        "",
        "| label | bag | messages | missing topics | fault time |",
        "|---|---|---|---|---|",
    ]
    for run, m in zip(runs, metrics, strict=True):
        counts = ", ".join(f"{t}: {n}" for t, n in sorted(run.data.counts.items()))
        missing = ", ".join(run.data.missing) or "none"
        lines.append(
            f"| {run.label} | `{run.data.path}` | {counts} | {missing} | "
            f"{m['fault_time']:.4g} s ({m['fault_time_source']}) |"
        )
    lines += ["", "## Figures", ""]
    for fig in figures:
        if fig.path is not None:
            lines += [f"### {fig.title}", "", f"![{fig.title}]({fig.path.name})", ""]
        else:
            lines += [f"### {fig.title}", "", f"Not drawn: {fig.reason}.", ""]
    lines += ["## Metrics", "", "[comparison.md](comparison.md)", ""]
    for run, p in zip(runs, metrics_paths, strict=True):
        lines.append(f"- {run.label}: [{p.parent.name}/{p.name}]({p.parent.name}/{p.name})")
    notes = [f"- {run.label}: {n}" for run in runs for n in run.data.notes]
    notes += [
        "- `contact_count` is simulator truth and not in a bag: null in these metrics.",
    ]
    lines += ["", "## Notes", "", *notes, ""]
    return "\n".join(lines)


def make_report(
    bags: list[str | Path],
    out: str | Path,
    labels: list[str] | None = None,
    scenario: str | Path | None = None,
    fault_time: float | None = None,
    namespace: str | None = None,
) -> dict:
    """Write the report of ``bags`` to ``out``; return ``{label: metrics}``.

    Parameters
    ----------
    bags : list of str or pathlib.Path
        rosbag2 folders.
    out : str or pathlib.Path
        Output folder (created).
    labels : list of str, optional
        One per bag.
    scenario : str or pathlib.Path, optional
        Scenario YAML (fault time and running speed as ``amb-sim``).
    fault_time : float, optional
        s, overrides the scenario's and the bags' fault times.
    namespace : str, optional
        The namespace the system ran in; None: found in each bag
        (:func:`amb_tools.bag_read.read_bag`).

    Returns
    -------
    dict
        label -> metrics (as written to ``<label>/metrics.json``).

    Raises
    ------
    ValueError
        If the number of labels differs from the number of bags, or a bag is unreadable
        (:class:`amb_tools.bag_read.BagReadError`).
    """
    # heavy, optional: matplotlib, only where figures are drawn (not for the tables and metrics)
    from amb_apps import report_figures as rf

    bags = [Path(b) for b in bags]
    if labels is None:
        labels = [default_label(b) for b in bags]
    if len(labels) != len(bags):
        raise ValueError(
            f"--labels has {len(labels)} label(s) for {len(bags)} bag(s); give one label per "
            "bag, comma-separated, in the order of the bags"
        )
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    sc_fault = sc_speed = sc_name = None
    if scenario is not None:
        sc_fault, sc_speed, sc_name = scenario_fault(scenario)
    runs, all_metrics, metric_paths = [], [], []
    taken: set[str] = set()
    for bag, label in zip(bags, labels, strict=True):
        data = read_bag(bag, namespace)
        fault = choose_fault_time(data, fault_time, sc_fault)
        m = bag_metrics(data, fault, sc_speed)
        if scenario is not None:
            m["scenario"] = str(scenario)
            m["scenario_name"] = sc_name
        m["label"] = label
        folder = out / slug(label, taken)
        folder.mkdir(exist_ok=True)
        known = fault.source in ("user", "scenario", "first_fault_event")
        runs.append(rf.Run(label, data, fault.time if known else None, fault.source))
        all_metrics.append(m)
        metric_paths.append(folder / "metrics.json")
    add_below_pid(all_metrics)
    for m, path in zip(all_metrics, metric_paths, strict=True):
        path.write_text(json.dumps(m, indent=2, default=json_default))
    figures = [
        rf.displacement_figure(runs, out / "displacement.png"),
        rf.one_x_figure(runs, out / "coefficients_1x.png"),
        rf.force_figure(runs, out / "forces.png"),
        rf.orbit_figure(runs, out / "orbits.png"),
        rf.timeline_figure(runs, out / "fault_timeline.png"),
    ]
    for run, p in zip(runs, metric_paths, strict=True):
        figures.append(rf.levels_figure(run, out / f"levels_{p.parent.name}.png"))
    (out / "comparison.md").write_text(comparison_table(labels, all_metrics))
    (out / "report.md").write_text(report_markdown(runs, figures, metric_paths, all_metrics))
    return dict(zip(labels, all_metrics, strict=True))


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``amb-report``."""
    args = build_parser().parse_args(argv)
    labels = None
    if args.labels is not None:
        labels = [s.strip() for s in args.labels.split(",")]
    try:
        result = make_report(
            args.bags, args.out, labels, args.scenario, args.fault_time, args.namespace
        )
    except (ValueError, TypeError, FileNotFoundError) as exc:
        print(f"amb-report: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(result, indent=2, default=json_default))
    else:
        for label, m in result.items():
            s = inner_summary(m)
            missing = ", ".join(m["missing_topics"]) or "none"
            print(
                f"{label}: inner steady 1x {_fmt(s['steady_1x'], 1e6, 2)} um, peak after fault "
                f"{_fmt(s['peak'], 1e6, 1)} um, settling {_fmt(s['settling'])} rev, peak "
                f"wavelet force {_fmt(s['peak_wavelet_force'])} N; missing topics: {missing}"
            )
        print(f"wrote {args.out}/report.md")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
