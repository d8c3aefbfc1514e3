"""
Figures of chapter 2 drawn with matplotlib (Agg) to PNG files, axes labelled with units.

Each function takes arrays from :mod:`amb_plant_sim.analysis` and a path, and returns the path.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from numpy.typing import NDArray

from amb_plant_sim.modal import Mode


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def plot_campbell(
    speeds_hz: NDArray, modes: list[list[Mode]], path: Path, title: str, n_modes: int = 8
) -> Path:
    """Campbell diagram (figure 2.7): frequency vs speed, forward/backward, synchronous line."""
    fig, ax = plt.subplots(figsize=(7, 5))
    style = {"forward": ("tab:red", "^"), "backward": ("tab:blue", "v"), "planar": ("k", "o")}
    seen = set()
    for f, ms in zip(speeds_hz, modes, strict=True):
        for m in ms[: 2 * n_modes]:
            c, mk = style[m.whirl]
            lab = None if m.whirl in seen else f"{m.whirl} whirl"
            seen.add(m.whirl)
            ax.plot(f, m.frequency_hz, mk, color=c, ms=4, label=lab)
    top = max((m.frequency_hz for ms in modes for m in ms[: 2 * n_modes]), default=1.0)
    s = np.linspace(0, max(speeds_hz), 10)
    ax.plot(s, s, "k--", lw=1, label="synchronous (1x)")
    ax.set_xlabel("running speed (Hz)")
    ax.set_ylabel("natural frequency (Hz)")
    ax.set_ylim(0, 1.05 * top)
    ax.set_title(title)
    ax.legend(loc="upper left")
    ax.grid(True, alpha=0.3)
    return _save(fig, path)


def plot_vs_elements(elements: list[int], freqs: NDArray, path: Path) -> Path:
    """Convergence of the first non-zero free-free frequencies with elements (figure 2.6)."""
    fig, ax = plt.subplots(figsize=(7, 5))
    for k in range(freqs.shape[1]):
        ax.plot(elements, freqs[:, k], "o-", label=f"mode {k + 1}")
    ax.set_xlabel("number of finite elements")
    ax.set_ylabel("natural frequency at zero speed (Hz)")
    ax.set_title("Free-free rotor: convergence with element count")
    ax.legend()
    ax.grid(True, alpha=0.3)
    return _save(fig, path)


def plot_vs_gain(kp: NDArray, freqs: NDArray, kz: float, path: Path) -> Path:
    """Natural frequencies against the proportional gain, I = D = 0 (figure 2.13)."""
    fig, ax = plt.subplots(figsize=(7, 5))
    for k in range(freqs.shape[1]):
        ax.plot(kp / 1e6, freqs[:, k], "-", label=f"mode {k + 1}")
    ax.axvline(kz / 1e6, color="k", ls="--", lw=1, label="negative stiffness K_z")
    ax.set_xlabel("proportional gain K_p (MN/m)")
    ax.set_ylabel("natural frequency (Hz)")
    ax.set_title("Zero-speed natural frequencies vs proportional gain (K_I = K_d = 0)")
    ax.legend()
    ax.grid(True, alpha=0.3)
    return _save(fig, path)


def plot_singular_values(freqs_hz: NDArray, sv: NDArray, path: Path) -> Path:
    """Singular values from AMB forces to sensors (figure 2.16)."""
    fig, ax = plt.subplots(figsize=(7, 5))
    for k in range(sv.shape[1]):
        ax.loglog(freqs_hz, sv[:, k] * 1e6, label=f"sigma {k + 1}")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("singular value (um/N)")
    ax.set_title("PID closed loop: AMB forces to sensors")
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)
    return _save(fig, path)


def plot_mode_shapes(
    z: NDArray,
    shapes: NDArray,
    freqs: list[float],
    path: Path,
    title: str,
    marks: dict[str, list[float]] | None = None,
) -> Path:
    """Mode shapes along the shaft (figures 2.4, 2.15), z from the drive end."""
    fig, ax = plt.subplots(figsize=(8, 5))
    for k, (sh, f) in enumerate(zip(shapes, freqs, strict=True)):
        ax.plot(z, sh, "o-", ms=3, label=f"mode {k + 1}: {f:.1f} Hz")
    for name, zs in (marks or {}).items():
        for j, zz in enumerate(zs):
            ax.axvline(zz, color="grey", ls=":", lw=1, label=name if j == 0 else None)
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("axial position z from the drive end (m)")
    ax.set_ylabel("normalised lateral displacement (-)")
    ax.set_title(title)
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    return _save(fig, path)


def plot_sensitivity(freqs_hz: NDArray, S: NDArray, axes: tuple[str, ...], path: Path) -> Path:
    """Sensitivity magnitude per bearing axis with the ISO 14839-3 zone limits."""
    fig, ax = plt.subplots(figsize=(7, 5))
    for k, name in enumerate(axes):
        ax.semilogx(freqs_hz, 20 * np.log10(np.abs(S[:, k])), label=name)
    for db, zone in ((9.5, "A/B"), (12.0, "B/C"), (14.0, "C/D")):
        ax.axhline(db, color="grey", ls="--", lw=1)
        ax.text(freqs_hz[0], db + 0.2, f"ISO 14839-3 {zone}", fontsize=8, color="grey")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("sensitivity |G_s| (dB)")
    ax.set_title("Sensitivity at each bearing axis (other loops closed)")
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)
    return _save(fig, path)
