"""
Figures of ``amb-fault-eval --figures DIR`` (matplotlib, Agg backend, PNG).

The conventions of :mod:`amb_apps.report_figures` (its DPI, palette PNG writer, µm, plane
names): displacement in µm, time in s from sample 0 (the simulator's sample instants, also on
a speed profile), detection ratios dimensionless (feature / threshold,
:mod:`amb_fault_monitor.features`).

* :func:`case_figure`: one scenario with one wavelet, in a window around the first true fault
  onset (2 revolutions before to 4 after, stretched to the detection of the events found
  there): (a) displacement x and y at the four sensor planes; (b) the monitor's detection
  ratio per level, max over planes, fixed and rotating frames, as step traces from the sample
  that completes each coefficient, with the threshold at 1; (c) the true onset(s) and, per
  ``FaultEvent``, its estimated onset, detection and decision (when inside the window). A
  last, compressed row shows the peak radial displacement per revolution over the whole run
  (window shaded). The title gives the case, wavelet, speed and each expected fault's
  detection delay and onset error (the chapter 5 scenarios: figures 5.1-5.18, 5.27).
* :func:`summary_figure`: per expected class (rows) and wavelet, the detection delay in
  revolutions and the onset error in finest-level supports of every matched case, with the
  issue 5 targets, and false alarms per simulated hour per wavelet in the title.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.lines import Line2D

from amb_apps.evaluation import CaseResult, SimulatedCase, sample_time
from amb_apps.report_figures import PLANE_NOTE, UM, save_figure
from amb_common.faults import FINAL, event_status
from amb_wavelet.levels import revolution_level

__all__ = ["case_figure", "case_window", "summary_figure"]

REVS_BEFORE = 2.0
REVS_AFTER = 4.0
REVS_MAX = 24.0  # the window stretches to a late detection, at most this far after the onset
RATIO_FLOOR = 1e-2  # lower limit of the log ratio axes
# issue 5 targets: detection delay (revolutions) per class, |onset error| (finest supports)
DETECTION_TARGET_REVS = {"MASS_LOSS": 1.0, "AUX_BEARING_CONTACT": 0.25}
ONSET_TARGET_SUPPORTS = 1.0
EVENT_COLOURS = ("tab:purple", "tab:brown", "tab:olive", "tab:cyan", "tab:pink", "tab:gray")
FRAME_TITLE = {
    "fixed": "fixed frame (x, y)",
    "rotating": "synchronously rotating frame (u, v)",
}


def case_window(case: SimulatedCase, result: CaseResult) -> tuple[int, int, int | None]:
    """
    Sample window drawn by :func:`case_figure`.

    Parameters
    ----------
    case : SimulatedCase
    result : CaseResult
        ``run_case`` on ``case``.

    Returns
    -------
    lo, hi : int
        First and last sample index of the window (within the run).
    anchor : int or None
        First true onset (sample index); else the first event's estimated onset; ``None``
        when the run has neither (the window is then the last ``REVS_BEFORE + REVS_AFTER``
        revolutions).
    """
    spr = case.samples_per_rev
    n = int(case.block.sample_index.size)
    truths = [m["true_onset_sample"] for m in result.matches if m["true_onset_sample"] is not None]
    onsets = [e["onset_sample_index"] for e in result.events]
    anchor = min(truths) if truths else (min(onsets) if onsets else None)
    if anchor is None:
        return max(0, n - int((REVS_BEFORE + REVS_AFTER) * spr)), n - 1, None
    lo = anchor - int(REVS_BEFORE * spr)
    hi = anchor + int(REVS_AFTER * spr)
    late = [
        e["detection_sample_index"]
        for e in result.events
        if lo <= e["onset_sample_index"] <= hi or lo <= e["detection_sample_index"] <= hi
    ]
    if late:
        hi = max(hi, min(max(late) + spr // 2, anchor + int(REVS_MAX * spr)))
    return max(0, lo), min(n - 1, hi), anchor


def _ratio_series(trace: list, frame: str) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Per level: sample indices and the largest plane ratio, in trace order."""
    out: dict[int, tuple[list, list]] = {}
    for n, level, f, _first, _last, ratio in trace:
        if f != frame:
            continue
        ns, rs = out.setdefault(level, ([], []))
        ns.append(n)
        rs.append(float(np.max(ratio)))
    return {j: (np.asarray(ns), np.asarray(rs)) for j, (ns, rs) in sorted(out.items())}


def _match_line(m: dict[str, Any], finest_support: int) -> str:
    """One expected fault's outcome for a title (two lines when long)."""
    head = f"{m['expected']}: reported {m['predicted']}"
    if "first_contact_peak_n" in m:
        head += f" (first simulated contact peak {m['first_contact_peak_n']:.0f} N)"
    if "detection_delay_revs" not in m:
        return head
    onset_supports = m["onset_error_samples"] / finest_support
    tail = (
        f"detection {m['detection_delay_revs']:+.2f} rev ({m['detection_delay_ms']:.1f} ms), "
        f"onset error {onset_supports:+.2f} finest supports ({m['onset_error_ms']:+.2f} ms), "
        f"decision {m['decision_delay_revs']:+.1f} rev"
    )
    return f"{head}, {tail}" if len(head) + len(tail) < 140 else f"{head}:\n{tail}"


def _tag(ax, t: float, text: str, colour: str, i: int) -> None:
    """Short tag ``text`` next to the marker at ``t`` (s), staggered down by ``i``."""
    ax.annotate(
        text,
        (t, 1.0 - 0.1 * (i % 4)),
        xycoords=("data", "axes fraction"),
        xytext=(2, -2),
        textcoords="offset points",
        fontsize=7,
        color=colour,
        va="top",
        bbox={"fc": "w", "ec": "none", "alpha": 0.7, "pad": 0.5},
    )


def _event_label(e: dict[str, Any]) -> str:
    """Class, plane and channel of an event, and its status (provisional classes)."""
    where = f" plane {e['plane']}" if e.get("plane") else ""
    if e.get("channel", -1) >= 0:
        where += f" ch {e['channel'] + 1}"
    evidence = e.get("evidence", {})
    status, revised = event_status(evidence)
    if status == FINAL and revised:
        status = f"final, provisionally {evidence['provisional_class']}"
    return f"{e['fault_type']}{where}" + (f" ({status})" if status else "")


def case_figure(case: SimulatedCase, result: CaseResult, trace: list, path: str | Path) -> Path:
    """
    Draw one scenario run with one wavelet (module notes) and write it as PNG.

    Parameters
    ----------
    case : SimulatedCase
        The simulated scenario (displacement in m).
    result : CaseResult
        ``run_case(case, wavelet, trace=trace)``.
    trace : list
        The monitor's recorded ratios (:attr:`FaultMonitor.trace
        <amb_fault_monitor.monitor.FaultMonitor>`).
    path : str or Path
        PNG to write.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    spr = case.samples_per_rev
    block = case.block
    lo, hi, anchor = case_window(case, result)

    def at(sample):  # s, the instant of a sample index (or of an array of them)
        return sample_time(block.time, sample)

    t = block.time
    win = slice(lo, hi + 1)
    t_lo, t_hi = t[lo], t[hi]

    fig = plt.figure(figsize=(12, 13.5))
    gs = fig.add_gridspec(5, 2, height_ratios=[1.0, 1.0, 1.35, 1.35, 0.8])
    disp = [fig.add_subplot(gs[0, 0])]
    disp += [fig.add_subplot(gs[r, c], sharex=disp[0]) for r, c in ((0, 1), (1, 0), (1, 1))]
    rat = [fig.add_subplot(gs[2, :], sharex=disp[0]), fig.add_subplot(gs[3, :], sharex=disp[0])]
    whole = fig.add_subplot(gs[4, :])

    # (a) displacement at the four planes
    x = block.displacement * UM
    for p, ax in enumerate(disp):
        ax.plot(t[win], x[win, 2 * p], color="tab:blue", lw=0.8, label=f"x{p + 1}")
        ax.plot(t[win], x[win, 2 * p + 1], color="tab:red", lw=0.8, label=f"y{p + 1}")
        ax.set_title(f"plane {p + 1} ({PLANE_NOTE[p + 1]})", fontsize=9)
        ax.set_ylabel("displacement (µm)", fontsize=8)
        ax.legend(fontsize=7, loc="upper left", ncol=2)

    # (b) detection ratios per level, max over planes
    R = revolution_level(spr)
    levels = sorted({e[1] for e in trace})
    cmap = plt.get_cmap("viridis")
    colour = {j: cmap(i / max(1, len(levels) - 1)) for i, j in enumerate(levels)}
    for ax, frame in zip(rat, ("fixed", "rotating"), strict=True):
        top = 1.0
        for j, (ns, rs) in _ratio_series(trace, frame).items():
            k0 = max(0, int(np.searchsorted(ns, lo)) - 1)
            k1 = int(np.searchsorted(ns, hi, side="right"))
            if k1 <= k0:
                continue
            r = np.maximum(rs[k0:k1], RATIO_FLOOR)
            top = max(top, float(r.max()))
            ax.step(
                at(ns[k0:k1]),
                r,
                where="post",
                color=colour[j],
                lw=1.0,
                label=f"level {j} ({2.0 ** (R - j):g} x)",
            )
        ax.axhline(1.0, color="k", lw=1.2, label="threshold (ratio 1)")
        ax.set_yscale("log")
        ax.set_ylim(RATIO_FLOOR, 2.0 * top)
        ax.set_ylabel("feature / threshold\n(max over planes)", fontsize=8)
        ax.set_title(f"detection ratio per level, {FRAME_TITLE[frame]}", fontsize=9)
        if not trace:
            ax.text(
                0.5,
                0.5,
                "monitor not calibrated in this run: no ratios",
                transform=ax.transAxes,
                ha="center",
                va="center",
            )
    rat[0].legend(fontsize=7, loc="center left", bbox_to_anchor=(1.0, 0.5))

    # (c) markers: true onsets (T1..), events (E1..: estimated onset, detection, decision),
    # tagged at the top of the ratio axes and described in the legend
    handles = [
        Line2D([], [], color="0.3", ls=":", label="estimated onset"),
        Line2D([], [], color="0.3", ls="-", label="detection (alarm)"),
        Line2D([], [], color="0.3", ls="-.", label="decision (event published)"),
    ]
    truths = [m for m in result.matches if m["true_onset_sample"] is not None]
    for i, m in enumerate(truths):
        s_true = m["true_onset_sample"]
        for ax in [*disp, *rat, whole]:
            ax.axvline(at(s_true), color="k", ls="--", lw=1.1)
        if lo <= s_true <= hi:
            _tag(rat[0], at(s_true), f"T{i + 1}", "k", i)
        label = f"T{i + 1} true {m['expected']}\n{at(s_true):.4f} s"
        handles.append(Line2D([], [], color="k", ls="--", label=label))
    marks = (
        ("onset_sample_index", ":"),
        ("detection_sample_index", "-"),
        ("decision_sample_index", "-."),
    )
    for i, e in enumerate(result.events):
        c = EVENT_COLOURS[i % len(EVENT_COLOURS)]
        for key, ls in marks:
            if lo <= e[key] <= hi:
                for ax in [*disp, *rat]:
                    ax.axvline(at(e[key]), color=c, ls=ls, lw=1.1)
        if lo <= e["detection_sample_index"] <= hi:
            _tag(rat[1], at(e["detection_sample_index"]), f"E{i + 1}", c, i)
        whole.axvline(at(e["detection_sample_index"]), color=c, lw=1.0)
        label = (
            f"E{i + 1} {_event_label(e)}"
            f"\nonset {at(e['onset_sample_index']):.4f} s, "
            f"detection {at(e['detection_sample_index']):.4f} s"
            f"\ndecision {at(e['decision_sample_index']):.4f} s"
        )
        handles.append(Line2D([], [], color=c, lw=2.0, label=label))
    rat[1].legend(handles=handles, fontsize=7, loc="center left", bbox_to_anchor=(1.0, 0.5))

    # whole run, compressed: peak radial displacement per revolution at each plane
    n_rev = block.sample_index.size // spr
    xr = block.displacement[: n_rev * spr].reshape(n_rev, spr, 4, 2)
    peak = np.hypot(xr[..., 0], xr[..., 1]).max(axis=1) * UM
    for p in range(4):
        whole.step(t[: n_rev * spr : spr], peak[:, p], where="post", lw=0.9, label=f"plane {p + 1}")
    whole.axvspan(t_lo, t_hi, color="tab:orange", alpha=0.15, label="window above")
    if result.calibration_end_sample is not None:
        whole.axvline(
            at(result.calibration_end_sample), color="0.5", ls="-.", lw=0.9, label="calibrated"
        )
    for k, n in enumerate(result.recalibration_samples):
        label = "calibrated again" if k == 0 else None
        whole.axvline(at(n), color="0.5", ls=":", lw=0.9, label=label)
    whole.set_title("whole run: peak radial displacement per revolution", fontsize=9)
    whole.set_ylabel("peak |r| (µm)", fontsize=8)
    whole.set_xlabel("time (s)")
    whole.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.0, 0.5))

    for ax in [*disp, *rat, whole]:
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=7)
    rat[1].set_xlabel("time (s)")
    disp[0].set_xlim(t_lo, t_hi)
    if anchor is not None:
        # the speed at the onset: revolutions over the window (a few) also on a run-up
        t0, speed = (
            at(anchor),
            float(block.omega[min(anchor, block.omega.size - 1)]) / (2 * math.pi),
        )
        for ax in disp[:2]:
            sec = ax.secondary_xaxis(
                "top", functions=(lambda v: (v - t0) * speed, lambda r: r / speed + t0)
            )
            sec.set_xlabel("revolutions from the first onset", fontsize=7)
            sec.tick_params(labelsize=7)

    hz = block.omega / (2 * math.pi)
    if np.ptp(hz) > 1e-9 * hz.max():
        speed_text = f"speed {hz[0]:.2f} to {hz[-1]:.2f} Hz"
    else:
        speed_text = f"{case.speed_hz:.2f} Hz ({2 * math.pi * case.speed_hz:.0f} rad/s)"
    lines = [f"{Path(case.path).stem}: wavelet {result.wavelet}, {speed_text}, {spr} samples/rev"]
    lines += [_match_line(m, result.finest_support) for m in result.matches]
    if result.false_alarms:
        lines.append(
            f"{len(result.false_alarms)} false alarm(s): "
            + ", ".join(
                f"{f['predicted']} at {f['detection_time']:.3f} s" for f in result.false_alarms
            )
        )
    if not result.matches and not result.false_alarms:
        lines.append("healthy run, no event")
    fig.suptitle("\n".join(lines), fontsize=9)
    fig.tight_layout()
    return save_figure(fig, Path(path))


def summary_figure(parts: dict[str, tuple[dict, list[CaseResult]]], path: str | Path) -> Path:
    """
    Detection delay and onset error of every matched case, per class and wavelet.

    Parameters
    ----------
    parts : dict
        Wavelet -> ``(summarise(results), results)``.
    path : str or Path
        PNG to write.

    Returns
    -------
    pathlib.Path
        ``path``.

    Notes
    -----
    Filled dots: classified correctly; red crosses: matched to an event of another class
    (delays still drawn); missed expected faults are counted in the panel. Points beyond the
    target are labelled with their scenario name.
    """
    wavelets = list(parts)
    classes = sorted({m["expected"] for _s, res in parts.values() for r in res for m in r.matches})
    rows = max(1, len(classes))
    fig, axes = plt.subplots(rows, 2, figsize=(12, 2.6 * rows + 1.2), squeeze=False)
    for ci, cls in enumerate(classes):
        for col, (what, unit) in enumerate(
            (("detection delay", "revolutions"), ("|onset error|", "finest-level supports"))
        ):
            ax = axes[ci, col]
            target = DETECTION_TARGET_REVS.get(cls) if col == 0 else ONSET_TARGET_SUPPORTS
            for wi, w in enumerate(wavelets):
                rows_w = [(r, m) for r in parts[w][1] for m in r.matches if m["expected"] == cls]
                got = [(r, m) for r, m in rows_w if "detection_delay_revs" in m]
                lost = len(rows_w) - len(got)
                offsets = np.linspace(-0.25, 0.25, len(got)) if len(got) > 1 else [0.0]
                for (r, m), dx in zip(got, offsets, strict=False):
                    if col == 0:
                        v = m["detection_delay_revs"]
                    else:
                        v = abs(m["onset_error_samples"]) / r.finest_support
                    ok = m["predicted"] == m["expected"]
                    ax.plot(
                        wi + dx,
                        v,
                        "o" if ok else "x",
                        color="tab:blue" if ok else "tab:red",
                        ms=4.5,
                        alpha=0.85,
                    )
                    if target is not None and v > target:
                        ax.annotate(
                            Path(r.path).stem,
                            (wi + dx, v),
                            xytext=(3, 0),
                            textcoords="offset points",
                            fontsize=6,
                            va="center",
                        )
                if lost:
                    ax.text(
                        wi,
                        1.0,
                        f"{lost} missed / not scored",
                        transform=ax.get_xaxis_transform(),
                        ha="center",
                        va="top",
                        fontsize=7,
                        color="tab:red",
                    )
            if target is not None:
                ax.axhline(target, color="k", ls="--", lw=1.0)
                ax.annotate(
                    f"target {target:g}",
                    (0.0, target),
                    xycoords=("axes fraction", "data"),
                    xytext=(3, 2),
                    textcoords="offset points",
                    fontsize=7,
                )
            ax.set_xticks(range(len(wavelets)), wavelets)
            ax.set_xlim(-0.6, len(wavelets) - 0.4)
            ax.set_ylim(0.0, 1.12 * max(ax.get_ylim()[1], target or 0.0))
            ax.set_title(f"{cls}: {what}", fontsize=9)
            ax.set_ylabel(unit, fontsize=8)
            ax.grid(alpha=0.3)
            ax.tick_params(labelsize=7)
    if not classes:
        for ax in axes[0]:
            ax.text(0.5, 0.5, "no expected fault in these scenarios", ha="center", va="center")
    fa = ", ".join(
        f"{w}: {s['false_alarms']} ({s['false_alarms_per_hour']:.0f}/h)"
        for w, (s, _r) in parts.items()
    )
    sim_s = next(iter(parts.values()))[0]["simulated_s"] if parts else 0.0
    correct = ", ".join(f"{w}: {s['correct']}/{s['total']}" for w, (s, _r) in parts.items())
    fig.suptitle(
        "Fault monitor over the scenario suite: detection delay and onset error per matched case"
        f"\ncorrectly classified {correct}; false alarms in {sim_s:.1f} s simulated {fa}"
        "\n(dots: correct class, red crosses: another class; dashed: issue 5 targets)",
        fontsize=9,
    )
    fig.tight_layout()
    return save_figure(fig, Path(path))
