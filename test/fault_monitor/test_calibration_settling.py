"""Calibration waits for a stationary window: a decaying start-up transient is not calibrated on.

Reference: for white probe noise of standard deviation ``sigma`` the orthonormal level-1 haar
detail has standard deviation ``sigma``; the normalised coefficient ``d / sqrt(2)`` and its
one-revolution change therefore ``sigma`` (two independent draws), and the plane feature
``hypot`` of the x and y changes is Rayleigh with scale ``sigma``. The robust threshold of a
Rayleigh variable (median + k * 1.4826 MAD) is computed here with scipy.stats, not the monitor.
"""

import numpy as np
import pytest
from scipy import optimize, stats
from synthetic import OMEGA, SPR, run_monitor

from amb_fault_monitor.config import MonitorConfig
from amb_fault_monitor.errors import FaultMonitorError
from amb_fault_monitor.monitor import FaultMonitor

SIGMA = 2e-7


def _rayleigh_threshold(scale: float, k: float) -> float:
    dist = stats.rayleigh(scale=scale)
    med = dist.median()
    # MAD: the m with P(|R - med| <= m) = 1/2
    mad = optimize.brentq(lambda m: dist.cdf(med + m) - dist.cdf(med - m) - 0.5, 0, 10 * scale)
    return med + k * 1.4826 * mad


def _run(n_revs: int, transient: float, seed: int = 0):
    n = n_revs * SPR
    idx = np.arange(n)
    t = idx / (SPR * OMEGA / (2 * np.pi))
    rng = np.random.default_rng(seed)
    xy = SIGMA * rng.standard_normal((n, 8))
    # start-up ring-down at 0.6 x speed, time constant 4 revolutions (2 rev at the feature)
    tau = 4 * 2 * np.pi / OMEGA
    ring = transient * np.exp(-t / tau)
    for p in range(4):
        xy[:, 2 * p] += ring * np.cos(0.6 * OMEGA * t)
        xy[:, 2 * p + 1] += ring * np.sin(0.6 * OMEGA * t)
    return xy, (2 * np.pi * idx / SPR) % (2 * np.pi), idx


def test_noise_only_threshold_matches_rayleigh_closed_form():
    xy, angle, idx = _run(60, transient=0.0)
    monitor = FaultMonitor(MonitorConfig(SPR))
    run_monitor(monitor, xy, angle, idx)
    thr = monitor.thresholds[(1, "fixed")]
    # 16 revolutions x 16 coefficients: the MAD of 256 values is known to ~10 %
    np.testing.assert_allclose(thr, _rayleigh_threshold(SIGMA, 8.0), rtol=0.2)
    assert monitor.calibration_retries == 0


def test_start_up_transient_is_waited_out():
    xy, angle, idx = _run(120, transient=50e-6)
    settled = FaultMonitor(MonitorConfig(SPR))
    run_monitor(settled, xy, angle, idx)
    eager = FaultMonitor(MonitorConfig(SPR, settle_ratio=1e9))  # the old behaviour
    run_monitor(eager, xy, angle, idx)
    ref = _rayleigh_threshold(SIGMA, 8.0)
    # the ring-down (50 um, tau = 4 rev) has decayed to the noise after ~20 revolutions
    assert settled.calibration_retries > 0
    assert settled.calibration_end > 20 * SPR
    np.testing.assert_allclose(settled.thresholds[(1, "fixed")], ref, rtol=0.25)
    for key, thr in settled.thresholds.items():
        assert np.all(thr < 3 * ref), key  # every level near the noise level
    assert eager.thresholds[(6, "fixed")].max() > 10 * settled.thresholds[(6, "fixed")].max()


def _late_disturbance(start_rev: int, n_revs: int = 80, seed: int = 0):
    """Noise, then from ``start_rev`` a new 1 x level (10 um) and a 20 um ring-down (tau 2 rev)."""
    n = n_revs * SPR
    idx = np.arange(n)
    t = idx / (SPR * OMEGA / (2 * np.pi))
    xy = SIGMA * np.random.default_rng(seed).standard_normal((n, 8))
    t0 = start_rev * 2 * np.pi / OMEGA
    on = t >= t0
    ring = np.where(on, 20e-6 * np.exp(-(t - t0) * OMEGA / (4 * np.pi)), 0.0)
    step = np.where(on, 10e-6, 0.0)
    for p in range(4):
        xy[:, 2 * p] += ring * np.cos(0.6 * OMEGA * (t - t0)) + step * np.cos(OMEGA * t)
        xy[:, 2 * p + 1] += ring * np.sin(0.6 * OMEGA * (t - t0)) + step * np.sin(OMEGA * t)
    return xy, (2 * np.pi * idx / SPR) % (2 * np.pi), idx


@pytest.mark.parametrize("start_rev", [12, 15])
def test_a_disturbance_at_the_end_of_the_window_is_not_calibrated_on(start_rev):
    # the window (16 revolutions of settled coefficients) would end at revolution 18: a
    # disturbance in its last revolutions moves neither half's median; before, the monitor
    # calibrated on it and then reported a MASS_LOSS whose onset was the calibration's end
    # (2-6 revolutions after the true one)
    xy, angle, idx = _late_disturbance(start_rev)
    monitor = FaultMonitor(MonitorConfig(SPR))
    events = run_monitor(monitor, xy, angle, idx)
    assert monitor.calibration_end > (start_rev + 4) * SPR  # after the ring-down
    assert events == []  # nothing to report: the disturbance came before the monitor was ready


def test_a_disturbance_after_calibration_is_still_found_at_its_onset():
    xy, angle, idx = _late_disturbance(30)
    monitor = FaultMonitor(MonitorConfig(SPR))
    events = run_monitor(monitor, xy, angle, idx)
    assert monitor.calibration_end < 30 * SPR
    assert [e.fault_type.name for e in events] == ["MASS_LOSS"]
    assert abs(events[0].onset_sample_index - 30 * SPR) <= 1


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"settle_ratio": 0.5}, "settle_ratio"), ({"settle_revs": 1}, "settle_revs")],
)
def test_settling_parameters_validated(kwargs, match):
    with pytest.raises(FaultMonitorError, match=match):
        MonitorConfig(SPR, **kwargs)
