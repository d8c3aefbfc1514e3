"""Thesis-style figures of one or more bags (matplotlib, Agg backend, PNG).

Each function takes the runs to draw (:class:`Run`: a label, the bag's arrays and its fault
time) and an output path, draws what the bags hold and returns a :class:`Figure` record (the
file written, or ``None`` and the reason when no bag has the data). Displacements in µm, forces
in N, time in s from the bag's header stamps (simulated time in lock step), wavelet
coefficients in µm √samples (orthonormal filters: the values published on
``/amb/wavelet/coefficients``, scaled by 1e6).

Figures (thesis numbering):

* :func:`displacement_figure`: displacement at the four sensor planes, x and y, runs
  overlaid (fig. 8.11 (a-d)/(e-h));
* :func:`one_x_figure`: the 1 x level coefficient ``x_{1,1}`` (even, odd, magnitude) per
  control period at the inner sensors (fig. 8.11 (e-h), 7.3);
* :func:`levels_figure`: fixed-frame even detail coefficients of every level at the inner x
  sensors (figs. 5.1-5.18);
* :func:`force_figure`: total AMB control force and wavelet control force per bearing axis
  (fig. 8.12);
* :func:`orbit_figure`: orbits at the four planes before the fault, in the first revolutions
  after it, and at the end of the run (fig. 5.27);
* :func:`timeline_figure`: per-revolution peak radial displacement at each plane with the
  ``FaultEvent`` onsets and detections (chapter 5).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import io

import matplotlib.pyplot as plt
import numpy as np
from PIL import Image

from amb_common import topics
from amb_common.names import AXIS_NAMES, SENSOR_NAMES
from amb_tools.bag_read import BagData

DPI = 110
UM = 1e6
COLOURS = ("tab:blue", "tab:red", "tab:green", "tab:orange", "tab:purple", "tab:brown")
PLANE_NOTE = {
    1: "non-driven end",
    2: "inner, beside AMB 1",
    3: "inner, beside AMB 2",
    4: "drive end",
}
INNER = (2, 3, 4, 5)
ORBIT_REVS_BEFORE = 2
ORBIT_REVS_TRANSIENT = 5
ORBIT_REVS_END = 2


@dataclass
class Run:
    """One bag to draw.

    Attributes
    ----------
    label : str
        Legend label (e.g. ``"PID only"``).
    data : BagData
    fault_time : float or None
        s; ``None`` when the run has no known fault.
    fault_source : str
        Where the fault time came from (scenario, FaultEvent, user).
    """

    label: str
    data: BagData
    fault_time: float | None
    fault_source: str = ""


@dataclass
class Figure:
    """A figure of the report: the file written, or why none was."""

    name: str
    title: str
    path: Path | None
    reason: str = ""


def _colour(i: int) -> str:
    return COLOURS[i % len(COLOURS)]


def save_figure(fig, path: Path) -> Path:
    """Write ``fig`` as a palette PNG (256 adaptive colours: a third of the RGBA size)."""
    buf = io.BytesIO()
    fig.savefig(buf, dpi=DPI, format="png")
    plt.close(fig)
    buf.seek(0)
    with Image.open(buf) as im:
        im.convert("RGB").quantize(colors=256).save(path)
    return path


def _mark_faults(ax, runs: list[Run], with_label: bool = False) -> None:
    seen: set[float] = set()
    for i, run in enumerate(runs):
        if run.fault_time is None or run.fault_time in seen:
            continue
        seen.add(run.fault_time)
        label = f"fault ({run.fault_source})" if with_label else None
        colour = (
            "k"
            if len(runs) == 1 or all(r.fault_time == run.fault_time for r in runs)
            else (_colour(i))
        )
        ax.axvline(run.fault_time, color=colour, ls="--", lw=0.9, label=label)


def displacement_figure(runs: list[Run], path: Path) -> Figure:
    """Displacement at each sensor (x, y at planes 1-4) vs time, runs overlaid (fig. 8.11).

    Parameters
    ----------
    runs : list of Run
    path : pathlib.Path
        PNG to write.

    Returns
    -------
    Figure
    """
    title = "Rotor displacement at the four sensor planes"
    have = [r for r in runs if r.data.measurements is not None]
    if not have:
        return Figure("displacement", title, None, "no /amb/measurement in any bag")
    fig, axes = plt.subplots(4, 2, figsize=(11, 9), sharex=True, sharey="row")
    for i, run in enumerate(runs):
        m = run.data.measurements
        if m is None:
            continue
        for c in range(8):
            ax = axes[c // 2, c % 2]
            ax.plot(
                m.time,
                m.displacement[:, c] * UM,
                color=_colour(i),
                lw=0.6,
                alpha=0.9 if i else 0.8,
                label=run.label,
            )
    for c in range(8):
        ax = axes[c // 2, c % 2]
        plane = c // 2 + 1
        ax.set_title(
            f"sensor {c + 1}: {SENSOR_NAMES[c]}, plane {plane} ({PLANE_NOTE[plane]})", fontsize=9
        )
        _mark_faults(ax, have, with_label=(c == 0))
        ax.grid(alpha=0.3)
        if c % 2 == 0:
            ax.set_ylabel("displacement (µm)")
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    axes[0, 0].legend(loc="upper left", fontsize=8, ncol=2)
    fig.suptitle(title + " (thesis fig. 8.11 style)", fontsize=11)
    fig.tight_layout()
    return Figure("displacement", title, save_figure(fig, path))


def one_x_figure(runs: list[Run], path: Path) -> Figure:
    """The 1 x wavelet coefficient per control period at the inner sensors (fig. 8.11 (e-h)).

    Even and odd (quadrature) channels of the fixed-frame detail at the 1 x level
    ``j = log2(samples_per_rev)`` and their magnitude ``|x_{1,1,even} + i x_{1,1,odd}|``.
    """
    title = "1 x wavelet coefficient per control period at the inner sensors"
    have = [r for r in runs if r.data.one_x is not None]
    if not have:
        return Figure(
            "coefficients_1x",
            title,
            None,
            "no 1 x level coefficients on /amb/wavelet/coefficients in any bag",
        )
    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharex=True, sharey=True)
    for i, run in enumerate(runs):
        ox = run.data.one_x
        if ox is None:
            continue
        k = np.arange(ox.even.shape[0])
        for a, c in enumerate(INNER):
            ax = axes.flat[a]
            mag = np.abs(ox.phasor[:, c]) * UM
            ax.plot(k, mag, "-o", color=_colour(i), ms=3.5, lw=1.4, label=f"{run.label}: magnitude")
            ax.plot(
                k,
                ox.even[:, c] * UM,
                ":",
                marker=".",
                color=_colour(i),
                lw=0.8,
                ms=4,
                label=f"{run.label}: even",
            )
            ax.plot(
                k,
                ox.odd[:, c] * UM,
                "--",
                marker="x",
                color=_colour(i),
                lw=0.8,
                ms=3,
                label=f"{run.label}: odd",
            )
    for a, c in enumerate(INNER):
        ax = axes.flat[a]
        ax.set_title(f"sensor {c + 1} ({SENSOR_NAMES[c]}), plane {c // 2 + 1}", fontsize=9)
        ax.axhline(0.0, color="0.5", lw=0.5)
        for i, run in enumerate(have):
            spr = run.data.samples_per_rev
            n_period = run.data.one_x.samples_per_period
            if run.fault_time is not None and spr:
                speed = run.data.speed_hz() or 0.0
                k_f = run.fault_time * speed * spr / n_period
                ax.axvline(
                    k_f, color="k", ls="--", lw=0.9, label="fault" if (a == 0 and i == 0) else None
                )
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("control period index k (revolutions)")
    for ax in axes[:, 0]:
        ax.set_ylabel(r"$x_{1,1}$ coefficient (µm $\sqrt{\mathrm{samples}}$)")
    axes[0, 0].legend(fontsize=7, ncol=1 + (len(have) > 1), loc="best")
    ox = have[0].data.one_x
    fig.suptitle(
        f"{title}\n({ox.wavelet}, filterbank level {ox.level} = 1 x running speed, fixed frame; "
        "thesis figs. 8.11 (e-h), 7.3)",
        fontsize=10,
    )
    fig.tight_layout()
    return Figure("coefficients_1x", title, save_figure(fig, path))


def levels_figure(run: Run, path: Path) -> Figure:
    """Fixed-frame even detail coefficients of every level at x2 and x3 (figs. 5.1-5.18)."""
    title = f"Wavelet coefficients per level, {run.label}"
    levels = run.data.levels
    if not levels:
        return Figure(
            f"levels_{run.label}",
            title,
            None,
            "no detail coefficients on /amb/wavelet/coefficients",
        )
    js = sorted(levels)
    fig, axes = plt.subplots(
        len(js), 2, figsize=(11, 1.3 * len(js) + 1.2), sharex=True, squeeze=False
    )
    speed = run.data.speed_hz() or 0.0
    for r, j in enumerate(js):
        lv = levels[j]
        t = run.data.sample_time(lv.sample_index)
        mult = lv.pseudo_frequency / speed if speed > 0 else float("nan")
        for col, c in enumerate((2, 4)):
            ax = axes[r, col]
            ax.plot(t, lv.values[:, c] * UM, "-", color=_colour(col), lw=0.7, marker=".", ms=2)
            ax.axhline(0, color="0.5", lw=0.4)
            if run.fault_time is not None:
                ax.axvline(run.fault_time, color="k", ls="--", lw=0.8)
            ax.grid(alpha=0.3)
            ax.tick_params(labelsize=7)
            ax.set_title(
                f"level {j} ({lv.pseudo_frequency:.1f} Hz = {mult:.3g} x), "
                f"sensor {SENSOR_NAMES[c]}",
                fontsize=8,
                pad=2,
            )
        axes[r, 0].set_ylabel("µm √samples", fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    fig.suptitle(
        f"{title}: fixed frame, even channel, inner x sensors (thesis figs. 5.1-5.18)", fontsize=10
    )
    fig.tight_layout()
    return Figure(f"levels_{run.label}", title, save_figure(fig, path))


def force_figure(runs: list[Run], path: Path) -> Figure:
    """Total and wavelet control force per bearing axis vs time (fig. 8.12)."""
    title = "Total AMB control force and wavelet control force per bearing axis"
    have = [r for r in runs if r.data.measurements is not None or r.data.commands is not None]
    if not have:
        return Figure(
            "forces", title, None, "neither /amb/measurement nor /amb/control/command in any bag"
        )
    fig, axes = plt.subplots(4, 2, figsize=(11, 9), sharex=True)
    notes = []
    for i, run in enumerate(runs):
        m, cmd = run.data.measurements, run.data.commands
        if m is not None:
            t, total, wavelet = m.time, m.bearing_force, m.wavelet_force
        elif cmd is not None:
            n = cmd.force.shape[2]
            samples = (cmd.start_sample_index[:, None] + np.arange(n)[None, :]).ravel()
            t = run.data.sample_time(samples)
            total, wavelet = None, cmd.force.transpose(0, 2, 1).reshape(-1, 4)
            notes.append(f"{run.label}: commanded wavelet force only (no /amb/measurement)")
        else:
            continue
        for a in range(4):
            if total is not None:
                axes[a, 0].plot(t, total[:, a], color=_colour(i), lw=0.6, label=run.label)
            axes[a, 1].plot(t, wavelet[:, a], color=_colour(i), lw=0.8, label=run.label)
    if all(r.data.measurements is None for r in have):
        for a in range(4):
            axes[a, 0].text(
                0.5,
                0.5,
                "not in the bag(s): no /amb/measurement",
                transform=axes[a, 0].transAxes,
                ha="center",
                va="center",
            )
    for a in range(4):
        b = a // 2 + 1
        end = "non-driven end" if b == 1 else "drive end"
        for col, what in enumerate(
            ("total control force (PID + wavelet)", "wavelet control force")
        ):
            ax = axes[a, col]
            ax.set_title(f"{what}, bearing {b} ({end}) {AXIS_NAMES[a][-1]}", fontsize=9)
            _mark_faults(ax, have, with_label=(a == 0 and col == 0))
            ax.grid(alpha=0.3)
            ax.set_ylabel("force (N)")
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    axes[0, 0].legend(fontsize=8, loc="upper left")
    sub = "; ".join(notes)
    fig.suptitle(title + " (thesis fig. 8.12 style)" + (f"\n{sub}" if sub else ""), fontsize=10)
    fig.tight_layout()
    return Figure("forces", title, save_figure(fig, path))


def _orbit_windows(run: Run) -> list[tuple[str, np.ndarray, dict]]:
    m = run.data.measurements
    spr = run.data.samples_per_rev
    n = m.time.size
    if run.fault_time is None or run.fault_time <= m.time[0]:
        i_f = None
    else:
        i_f = int(np.searchsorted(m.time, run.fault_time - 0.5e-9))
    wins = []
    if i_f is not None and i_f > 0:
        a = max(0, i_f - ORBIT_REVS_BEFORE * spr)
        wins.append(
            (
                f"before the fault ({(i_f - a) / spr:.0f} rev)",
                np.arange(a, i_f),
                {"color": "tab:blue", "lw": 1.4},
            )
        )
        b = min(n, i_f + ORBIT_REVS_TRANSIENT * spr)
        wins.append(
            (
                f"first {(b - i_f) / spr:.0f} rev after the fault",
                np.arange(i_f, b),
                {"color": "tab:red", "lw": 0.6, "alpha": 0.8},
            )
        )
        start_end = max(b, n - ORBIT_REVS_END * spr)
    else:
        start_end = max(0, n - ORBIT_REVS_END * spr)
    if start_end < n:
        wins.append(
            (
                f"end of run (last {(n - start_end) / spr:.0f} rev)",
                np.arange(start_end, n),
                {"color": "k", "lw": 1.4},
            )
        )
    return wins


def orbit_figure(runs: list[Run], path: Path) -> Figure:
    """Orbits (x vs y) at each plane before and after the fault, one row per run (fig. 5.27)."""
    title = "Rotor orbits at the four sensor planes"
    have = [r for r in runs if r.data.measurements is not None and r.data.samples_per_rev]
    if not have:
        return Figure("orbits", title, None, "no /amb/measurement in any bag")
    fig, axes = plt.subplots(len(have), 4, figsize=(12, 3.0 * len(have) + 0.7), squeeze=False)
    lim = np.zeros(4)
    for run in have:
        x = run.data.measurements.displacement
        lim = np.maximum(lim, np.abs(x).reshape(-1, 4, 2).max(axis=(0, 2)) * UM)
    for r, run in enumerate(have):
        x = run.data.measurements.displacement * UM
        for p in range(4):
            ax = axes[r, p]
            for label, idx, style in _orbit_windows(run):
                ax.plot(x[idx, 2 * p], x[idx, 2 * p + 1], label=label, **style)
            # the (small) steady orbit before the fault drawn last, on top
            for line in [ln for ln in ax.get_lines() if ln.get_label().startswith("before")]:
                line.set_zorder(3)
            ax.set_aspect("equal", adjustable="box")
            L = 1.05 * lim[p] if lim[p] > 0 else 1.0
            ax.set_xlim(-L, L)
            ax.set_ylim(-L, L)
            ax.axhline(0, color="0.6", lw=0.4)
            ax.axvline(0, color="0.6", lw=0.4)
            ax.grid(alpha=0.3)
            ax.tick_params(labelsize=7)
            ax.set_title(f"{run.label}: plane {p + 1} ({PLANE_NOTE[p + 1]})", fontsize=8)
            ax.set_xlabel(f"x{p + 1} (µm)", fontsize=8)
            ax.set_ylabel(f"y{p + 1} (µm)", fontsize=8)
        axes[r, 0].legend(fontsize=7, loc="upper left")
    fig.suptitle(
        title + " before and after the fault (thesis fig. 5.27 style; equal axes, "
        "common scale per plane)",
        fontsize=10,
    )
    fig.tight_layout()
    return Figure("orbits", title, save_figure(fig, path))


def revolution_envelope(data: BagData) -> tuple[np.ndarray, np.ndarray]:
    """
    Return ``(t, peak)`` per whole revolution.

    The time at its start and the peak radial displacement ``max_n hypot(x_p[n], y_p[n])`` at
    each plane ``p`` (m, ``(R, 4)``).
    """
    m = data.measurements
    spr = data.samples_per_rev
    n_rev = m.time.size // spr
    x = m.displacement[: n_rev * spr].reshape(n_rev, spr, 4, 2)
    radial = np.hypot(x[..., 0], x[..., 1]).max(axis=1)
    return m.time[: n_rev * spr : spr], radial


def timeline_figure(runs: list[Run], path: Path) -> Figure:
    """FaultEvents (onset, detection) over the per-revolution displacement envelope."""
    title = "Fault timeline over the displacement envelope"
    have = [r for r in runs if r.data.measurements is not None and r.data.samples_per_rev]
    if not have:
        return Figure("fault_timeline", title, None, "no /amb/measurement in any bag")
    fig, axes = plt.subplots(
        len(have), 1, figsize=(11, 2.9 * len(have) + 0.9), squeeze=False, sharex=True
    )
    plane_colours = ("tab:blue", "tab:orange", "tab:green", "tab:purple")
    for r, run in enumerate(have):
        ax = axes[r, 0]
        t, env = revolution_envelope(run.data)
        for p in range(4):
            ax.step(
                t,
                env[:, p] * UM,
                where="post",
                color=plane_colours[p],
                lw=1.0,
                label=f"plane {p + 1}",
            )
        if run.fault_time is not None:
            ax.axvline(
                run.fault_time, color="k", ls="--", lw=1.0, label=f"fault time ({run.fault_source})"
            )
        events = run.data.fault_events
        top = float(env.max() * UM) if env.size else 1.0
        for e_i, e in enumerate(events):
            t_on = float(run.data.sample_time(e["onset_sample_index"]))
            t_det = float(run.data.sample_time(e["detection_sample_index"]))
            dec = e.get("decision_sample_index")
            t_dec = float(run.data.sample_time(dec)) if dec is not None else t_det
            ax.axvspan(
                t_on,
                t_dec,
                color="tab:red",
                alpha=0.12,
                label="onset to decision" if e_i == 0 else None,
            )
            ax.axvline(
                t_on, color="tab:red", lw=1.0, ls=":", label="estimated onset" if e_i == 0 else None
            )
            ax.axvline(
                t_dec,
                color="tab:red",
                lw=1.2,
                label="classified (event published)" if e_i == 0 else None,
            )
            ax.annotate(
                f"{e['fault_type']}"
                + (f" plane {e['plane']}" if e["plane"] else "")
                + f"\nonset {t_on:.3f} s, decided {t_dec:.3f} s",
                (t_dec, top * (0.95 - 0.22 * (e_i % 4))),
                fontsize=7,
                color="tab:red",
                xytext=(4, 0),
                textcoords="offset points",
                va="top",
            )
        if not events:
            msg = "no FaultEvent in this bag"
            events_topic = run.data.topic(topics.FAULT_EVENTS)
            if events_topic in run.data.missing:
                msg += f" ({events_topic} empty or not recorded: fault monitor not running?)"
            ax.text(
                0.01,
                0.95,
                msg,
                transform=ax.transAxes,
                fontsize=8,
                va="top",
                bbox={"fc": "w", "ec": "0.7"},
            )
        ax.set_title(f"{run.label}: peak radial displacement per revolution", fontsize=9)
        ax.set_ylabel("peak |r| per rev (µm)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.0, 0.5))
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle(
        title + " (FaultEvent onset = first crossing back-dated by the wavelet "
        "support, thesis chapter 5)",
        fontsize=10,
    )
    fig.tight_layout()
    return Figure("fault_timeline", title, save_figure(fig, path))
