"""Synthetic rotor responses for the fault-monitor tests (scipy.signal.lsim, not the monitor).

An isotropic two-mode oscillator per sensor plane, ``z = x + i y``:
``z'' + 2 zeta w z' + w**2 z = f(t)`` for each mode (natural frequencies 0.6 and 4.3 x the
running speed), so the response to a step in synchronous forcing (eq. 5.1) has a transient
and a new steady orbit, and the response to a short radial impulse (eq. 5.5, 1/20 of a
revolution) rings at both modes and dies away.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from amb_fault_monitor.records import FilterbankAdapter

SPR = 32
HZ = 29.0
OMEGA = 2 * np.pi * HZ
MODES = ((0.6, 0.15), (4.3, 0.05))  # (w / Omega, zeta)
PLANE_GAIN = np.array([1.0, 0.6, 0.5, 0.9])


def _respond(force: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Complex displacement (m) of one plane to a complex force per unit modal mass."""
    z = np.zeros_like(force)
    for ratio, zeta in MODES:
        w = ratio * OMEGA
        sys = signal.lti([1.0], [1.0, 2 * zeta * w, w * w])
        for part, unit in ((force.real, 1.0), (force.imag, 1j)):
            _, y, _ = signal.lsim(sys, part, t)
            z = z + unit * y
    return z


def make_run(
    n_revs: int,
    *,
    mass_loss_rev: float | None = None,
    contact_rev: float | None = None,
    unbalance: float = 0.4,
    loss: float = 0.4,
    loss_angle: float = 1.0,
    contact: float = 5.0,
    noise: float = 2e-7,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Displacements (n, 8) m, angles (n,) rad and sample indices of a synthetic run.

    Forces are per unit modal mass (m/s^2); ``unbalance`` and ``loss`` scale ``e Omega**2``.
    """
    n = n_revs * SPR
    idx = np.arange(n)
    t = idx / (SPR * HZ)
    theta = 2 * np.pi * idx / SPR
    f = unbalance * np.exp(1j * theta)
    if mass_loss_rev is not None:
        f = f + loss * np.exp(1j * (theta + loss_angle)) * (idx >= mass_loss_rev * SPR)
    if contact_rev is not None:
        n0 = int(contact_rev * SPR)
        width = max(1, SPR // 20)
        pulse = np.zeros(n)
        pulse[n0 : n0 + width] = contact
        f = f - pulse * np.exp(1j * 0.7)  # radial push towards the centre (eq. 5.5, mu = 0)
    z = _respond(f.astype(complex), t)
    rng = np.random.default_rng(seed)
    xy = np.zeros((n, 8))
    for p in range(4):
        xy[:, 2 * p] = PLANE_GAIN[p] * z.real
        xy[:, 2 * p + 1] = PLANE_GAIN[p] * z.imag
    xy += noise * rng.standard_normal(xy.shape)
    return xy, theta % (2 * np.pi), idx


def run_monitor(monitor, xy, angle, idx, wavelet: str = "haar"):
    """Drive the monitor through the filterbank core; return the events."""
    adapter = FilterbankAdapter(SPR, wavelet)
    events = []
    for i in range(len(idx)):
        events += monitor.step(adapter.step(int(idx[i]), xy[i], angle[i], OMEGA))
    return events


def add_base_motion(
    xy: np.ndarray,
    idx: np.ndarray,
    *,
    start_rev: float,
    amplitude: float = 40e-6,
    hz: float = 3.0,
    duration: float = 1.0,
    axis: int = 0,
    gains: tuple[float, float, float, float] = (1.0, 0.8, 0.6, 1.0),
) -> np.ndarray:
    """
    Add a slow relative displacement, in phase on all four planes, along ``axis`` (0 x, 1 y).

    ``amplitude * sin(2 pi hz (t - t0))`` for ``duration`` s from revolution ``start_rev``,
    scaled per plane by ``gains``: the rotor's motion relative to a moving base below 1 x
    (eq. 3.6; the simulated rig shows 30-60 um at 2-3 Hz, all planes together).
    """
    out = xy.copy()
    t = idx / (SPR * HZ)
    t0 = start_rev / HZ
    on = (t >= t0) & (t < t0 + duration)
    s = np.where(on, amplitude * np.sin(2 * np.pi * hz * (t - t0)), 0.0)
    for p in range(4):
        out[:, 2 * p + axis] += gains[p] * s
    return out
