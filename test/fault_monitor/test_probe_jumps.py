"""The jump test of one probe's reading (amb_fault_monitor.probe_jumps) on closed-form signals.

A synchronous vibration with Gaussian probe noise calibrates the test; a step of one channel's
reading (an offset), a change of slope (an impact), a step of two channels and a force step
(a change of curvature) follow. The references are the signals' own definitions: the step's
size and sample, which no rotor motion can produce.
"""

import numpy as np
import pytest

from amb_common.faults import FaultType
from amb_fault_monitor.config import MonitorConfig
from amb_fault_monitor.errors import FaultMonitorError
from amb_fault_monitor.probe_jumps import ProbeJumps, jump_decision

SPR = 32
CONFIG = MonitorConfig(SPR, calibration_revs=8.0)
NOISE = 2e-7  # m, the suite's probe noise
A = 100e-6  # m, vibration amplitude
CAL_END = 12 * SPR  # the sample at which the monitor would calibrate
ONSET = 15 * SPR + 7


def _stream(change=None, seed=1):
    """Twenty revolutions of 1 x vibration (8 channels, phases spread) plus noise, m."""
    n = np.arange(20 * SPR)
    phase = np.arange(8) * 0.7
    x = A * np.sin(2 * np.pi * n[:, None] / SPR + phase)
    x += np.random.default_rng(seed).normal(0.0, NOISE, x.shape)
    if change is not None:
        x += change(n)
    return x


def _run(x):
    jumps = ProbeJumps(CONFIG)
    for n, row in enumerate(x):
        jumps.add(n, row)
        if n == CAL_END:
            jumps.calibrate(CAL_END)
    return jumps


def _after(n, onset=ONSET):
    return (n >= onset).astype(float)


def test_the_threshold_is_the_largest_healthy_jump_of_each_channel():
    x = _stream()
    jumps = _run(x)
    s = (3 * (x[2:-1] - x[1:-2]) + x[:-3] - x[3:]) / 2  # s of samples 3..
    first = CAL_END - int(CONFIG.calibration_revs) * SPR
    # the kept revolutions start at sample 7 (the first full test) and run in whole
    # revolutions: those inside the window
    starts = range(7, CAL_END, SPR)
    window = [k for k in starts if k >= first and k + SPR <= CAL_END + 1]
    expected = np.max([np.abs(s[k - 3 : k - 3 + SPR]).max(axis=0) for k in window], axis=0)
    assert jumps.threshold == pytest.approx(expected, rel=1e-12)
    # noise-dominated: 2.24 sigma is the jump statistic's standard deviation
    assert np.all(jumps.threshold > 2.24 * NOISE) and np.all(jumps.threshold < 6 * 2.24 * NOISE)
    assert list(jumps.jumps) == []


@pytest.mark.parametrize("size", [10e-6, -20e-6])  # over jump_factor x the threshold (< 2.7 um)
def test_an_offset_of_one_probe_is_one_jump_of_its_size_at_its_first_sample(size):
    channel = 5
    x = _stream(lambda n: np.outer(_after(n) * size, np.eye(8)[channel]))
    jumps = _run(x)
    assert len(jumps.jumps) == 1, list(jumps.jumps)
    sample, ch, ratio, jump = jumps.jumps[0]
    assert (sample, ch) == (ONSET, channel)
    assert jump == pytest.approx(size, abs=4 * 2.24 * NOISE)
    assert ratio >= CONFIG.jump_factor
    mask = np.ones(8, dtype=bool)
    assert jumps.single_channel(ONSET - 8, ONSET + 64, mask) == jumps.jumps[0]
    assert jumps.single_channel(ONSET + 1, ONSET + 64, mask) is None  # outside the span
    mask[channel] = False
    assert jumps.single_channel(ONSET - 8, ONSET + 64, mask) is None  # a channel found faulty
    d = jump_decision(jumps.jumps[0], CONFIG.jump_factor)
    assert (d.fault_type, d.channel, d.plane) == (FaultType.SENSOR_FAULT, channel, 3)
    assert d.severity == pytest.approx(abs(size), abs=4 * 2.24 * NOISE)
    assert 0.0 < d.confidence <= 1.0


def test_an_impact_a_curvature_step_and_a_jump_of_two_probes_are_no_jumps():
    dv = 20e-6  # m per sample: a change of slope as large as the offset above

    def impact(n):  # the slope of channels 2 and 3 reverses by dv between two samples
        ramp = np.where(n >= ONSET, (n - ONSET + 0.4) * dv, 0.0)
        return np.outer(ramp, [0, 0, 1.0, 0.6, 0, 0, 0, 0])

    def curvature(n):  # a force step: the acceleration of every channel steps
        k = np.clip(n - ONSET, 0, None).astype(float)
        return np.outer(0.5 * k**2 * 1e-7, np.linspace(1.0, 0.3, 8))

    def two(n):  # channels 0 and 1 step together: the rotor would have moved
        return np.outer(_after(n) * 20e-6, [1.0, 0.8, 0, 0, 0, 0, 0, 0])

    for change in (impact, curvature, two):
        jumps = _run(_stream(change))
        assert list(jumps.jumps) == [], change.__name__


def test_jumps_on_two_channels_name_none():
    x = _stream(
        lambda n: (
            np.outer(_after(n) * 20e-6, np.eye(8)[1])
            + np.outer(_after(n, ONSET + 40) * 20e-6, np.eye(8)[6])
        )
    )
    jumps = _run(x)
    assert [j[:2] for j in jumps.jumps] == [(ONSET, 1), (ONSET + 40, 6)]
    mask = np.ones(8, dtype=bool)
    assert jumps.single_channel(ONSET - 8, ONSET + 64, mask) is None
    assert jumps.single_channel(ONSET - 8, ONSET + 39, mask)[1] == 1


def test_a_gap_in_the_samples_restarts_the_differences():
    """A missing sample would look like a jump of every channel: no test across it."""
    x = _stream()
    jumps = ProbeJumps(CONFIG)
    for n, row in enumerate(x):
        if n in (ONSET, ONSET + 1):
            continue  # two samples lost
        jumps.add(n if n < ONSET else n + 30, row)  # and the index jumps on
        if n == CAL_END:
            jumps.calibrate(CAL_END)
    assert list(jumps.jumps) == []


@pytest.mark.parametrize("field", ["jump_factor", "jump_isolation", "jump_lasting"])
def test_bad_jump_settings_are_refused(field):
    with pytest.raises(FaultMonitorError, match=field):
        MonitorConfig(SPR, **{field: 0.0})
