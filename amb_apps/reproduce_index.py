"""
The index of ``make reproduce`` (``OUT/index.md``), with why for each check not reproduced.

Per experiment: the thesis's words, our numbers, each check marked reproduced or not, and
the figures.

:func:`write_index` writes it from what :mod:`amb_apps.reproduce` measured. The summary table
at the top lists every experiment with the checks it reproduced and, for those it did not,
the check and its ``why_not`` line of ``config/reproduce.yaml``: the measured reason, written
where the check is defined, shown only when the check fails (a check that passes says
nothing). The facts a reason rests on that change with the model are in the runs' tables
(contact onsets, the radius of the controller's loop on its own model), not in the text.
"""

from __future__ import annotations

from pathlib import Path

#: figures of an experiment in the index: amb-report's, amb-prediction's per wavelet, and
#: amb-fault-eval's summary
REPORT_FIGURES = ("displacement.png", "forces.png", "coefficients_1x.png")
PREDICTION_FIGURES = ("signal", "coefficients")
FAULT_FIGURES = ("figures/summary.png",)


def fmt(metric: str, value: float | None) -> str:
    """A metric's value in its unit, as the index prints it (``-`` for none)."""
    if value is None:
        return "-"
    if metric.endswith("_s"):
        return f"{value:.2f} s"
    if metric in ("amplitude_error", "rebound"):
        return f"{100 * value:.1f} %"
    if metric in ("steady_1x_inner", "peak_inner"):
        return f"{value * 1e6:.1f} µm"
    if metric == "settling":
        return f"{value:.0f} rev"
    if metric == "model_radius":
        return f"{value:.3f}"
    if metric == "misclassified":
        return f"{value:.0f} wrong or missed"
    if metric in ("contacts", "false_alarms"):
        return f"{value:.0f}"
    return f"{value:.1f} N"


def _run_table(results: dict) -> list[str]:
    """The numbers of a closed-loop experiment's runs (markdown rows)."""
    lines = [
        "| run | steady 1x (inner) | peak after fault (inner) | settling | rebound | "
        "peak wavelet force | contact onsets | own-model radius |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for label, r in results.items():
        cells = [
            fmt(m, r.get(m))
            for m in (
                "steady_1x_inner",
                "peak_inner",
                "settling",
                "rebound",
                "peak_wavelet_force",
                "contacts",
                "model_radius",
            )
        ]
        if r.get("radius_without_error") is not None:  # a run with a deliberate model error
            cells[-1] += f" ({fmt('model_radius', r['radius_without_error'])} without the error)"
        lines.append(f"| {label} | {' | '.join(cells)} |")
    return lines


def _prediction_table(results: dict) -> list[str]:
    """The numbers of a steady-state prediction experiment, per wavelet (markdown rows)."""
    lines = ["| wavelet | measured settles | predicted settles | final 1x amplitude error |"]
    lines += ["|---|---:|---:|---:|"]
    for w, r in results.items():
        lines.append(
            f"| {w} | {fmt('measured_settling_s', r['measured_settling_s'])} | "
            f"{fmt('predicted_settling_s', r['predicted_settling_s'])} | "
            f"{fmt('amplitude_error', r['amplitude_error'])} |"
        )
    return lines


def _fault_table(summaries: dict) -> list[str]:
    """Per wavelet and fault class: cases, classified right, detection and decision delays."""
    lines = [
        "| wavelet | fault | expected | classified right | detection median / max | "
        "decision median / max | onset error max |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    for w, s in summaries.items():
        confusion = s["confusion"]
        for cls, d in s["delays"].items():
            row = confusion.get(cls, {})
            lines.append(
                f"| {w} | {cls} | {sum(row.values())} | {row.get(cls, 0)} | "
                f"{d['detection_ms_median']:.1f} ms / {d['detection_revs_max']:.2f} rev | "
                f"{d['decision_revs_median']:.1f} / {d['decision_revs_max']:.1f} rev | "
                f"{d['onset_error_abs_supports_max']:.1f} supports |"
            )
        lines.append(
            f"| {w} | healthy runs and the rest of each run | - | - | "
            f"false alarms: {s['false_alarms']} in {s['simulated_s']:.0f} s | | |"
        )
    return lines


def _check_rows(checks: list[dict]) -> list[str]:
    lines = ["| check | measured | bound | reproduced |", "|---|---:|---:|:---:|"]
    for c in checks:
        if "relative_to" in c:
            measured = f"{c['measured']:.3g} x {c['relative_to']}"
            bound = f"{c['op']} {c['value']:g}"
        else:
            measured = fmt(c["metric"], c["measured"])
            bound = f"{c['op']} {fmt(c['metric'], c['value'])}"
        lines.append(f"| {c['what']} | {measured} | {bound} | {'yes' if c['ok'] else 'NO'} |")
    return lines


def not_reproduced(checks: list[dict]) -> list[str]:
    """One line per failed check: what it checks and why it fails (its ``why_not``)."""
    return [
        f"**{c['what']}**: {' '.join(c.get('why_not', 'no reason recorded').split())}"
        for c in checks
        if not c["ok"]
    ]


def _figures(exp: dict, d: dict, rel: Path) -> list[str]:
    kind = exp.get("kind")
    if kind == "prediction":
        names = [f"prediction_{w}_{part}.png" for w in d["results"] for part in PREDICTION_FIGURES]
        lines = [""]
    elif kind == "faults":
        names = list(FAULT_FIGURES)
        lines = ["", f"Per-case figures: [{rel}/figures]({rel}/figures)", ""]
    else:
        names = [f"report/{fig}" for fig in REPORT_FIGURES]
        lines = ["", f"Report: [{rel}/report/report.md]({rel}/report/report.md)", ""]
    lines += [f"![{Path(f).name}]({rel}/{f})" for f in names if (d["folder"] / f).exists()]
    return lines


def _frequency_table(frequencies: dict) -> list[str]:
    """The model's natural frequencies and critical speeds against the thesis's (markdown)."""
    lines = ["| rig model (Hz) | thesis | this model | model / thesis - 1 |", "|---|---|---|---|"]
    names = {"natural": "PID-supported natural frequencies", "critical": "critical speeds"}
    for key, (thesis, model) in frequencies.items():
        cells = [
            " / ".join(f"{v:g}" for v in thesis),
            " / ".join(f"{v:.2f}" for v in model),
            " / ".join(f"{100 * (m / t - 1):+.1f} %" for m, t in zip(model, thesis, strict=True)),
        ]
        lines.append(f"| {names.get(key, key)} | {' | '.join(cells)} |")
    return [*lines, ""]


def write_index(
    out: Path,
    manifest: dict,
    done: dict,
    failed: dict | None = None,
    frequencies: dict | None = None,
) -> Path:
    """
    Write ``OUT/index.md``.

    Parameters
    ----------
    out : Path
        The output folder of ``make reproduce``.
    manifest : dict
        ``config/reproduce.yaml``.
    done : dict
        Experiment id -> ``{"results", "checks", "folder"}`` (and ``"summaries"`` for the
        fault suite) of the experiments that ran.
    failed : dict, optional
        Experiment id -> the error of a run that failed: listed in the summary with it.
    frequencies : dict, optional
        ``{name: (thesis, model)}`` in Hz (:func:`amb_apps.reproduce.model_frequencies`):
        a table before the summary, since every experiment runs at the model's own speeds.

    Returns
    -------
    Path
        The index.
    """
    lines = ["# Thesis experiments reproduced in simulation", ""]
    lines += [
        "Each experiment ran in the simulator (FE rotor of `config/rig.yaml`, local PID, the "
        "thesis's fault), with the wavelet model identified on-line at its speed. Numbers: "
        "`amb_controller/metrics.py` (inner sensors x2, y2, x3, y3; steady 1x over the last 10 "
        "revolutions; settling to 5 % of the 1x phasor's largest excursion; rebound: the "
        "largest rise of the per-revolution peak after its first fall, a fraction of the peak; "
        "contact onsets: simulator truth). The rig speeds 11, 18 and 29 Hz are the model's own "
        "first three critical speeds.",
        "",
        *(_frequency_table(frequencies) if frequencies else []),
        "| experiment | checks reproduced | not reproduced, and why |",
        "|---|---|---|",
    ]
    failed = failed or {}
    ran = [exp for exp in manifest["experiments"] if exp["id"] in done]
    for exp in manifest["experiments"]:
        if exp["id"] in failed:
            error = " ".join(str(failed[exp["id"]]).split())
            lines.append(f"| {exp['title']} | run failed | {error} |")
        elif exp["id"] in done:
            checks = done[exp["id"]]["checks"]
            why = "<br>".join(not_reproduced(checks)) or "-"
            n_ok = sum(c["ok"] for c in checks)
            lines.append(f"| [{exp['title']}](#{exp['id']}) | {n_ok} of {len(checks)} | {why} |")
    for exp in ran:
        d = done[exp["id"]]
        lines += ["", f"## {exp['title']}", "", f'<a id="{exp["id"]}"></a>', ""]
        lines += [f"Thesis (figures {exp['figures']}): {' '.join(exp['thesis'].split())}", ""]
        if exp.get("kind") == "prediction":
            lines += _prediction_table(d["results"])
        elif exp.get("kind") == "faults":
            lines += _fault_table(d["summaries"])
        else:
            lines += _run_table(d["results"])
        lines += ["", *_check_rows(d["checks"])]
        lines += [f"\nNot reproduced: {line}" for line in not_reproduced(d["checks"])]
        lines += _figures(exp, d, d["folder"].relative_to(out))
    path = out / "index.md"
    path.write_text("\n".join(lines) + "\n")
    return path
