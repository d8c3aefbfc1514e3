"""The loop-bias check: one-revolution means of the bearing force and their held steps.

References are closed forms: a 1 x sinusoid sums to zero over a whole revolution, so the mean
of ``F0 + A cos(2 pi k / N + phi)`` over one is ``F0``.
"""

import numpy as np
import pytest

from amb_fault_monitor.config import MonitorConfig
from amb_fault_monitor.loop_bias import LoopBias

SPR = 32
CHANNELS = (2, 3, 4, 5)  # x2, y2, x3, y3: the inner probes, as in config/rig.yaml
F0 = np.array([120.0, -40.0, 80.0, 10.0])  # N, the static (gravity) load per axis
AMP = np.array([300.0, 250.0, 150.0, 120.0])  # N, 1 x force amplitude


def _force(n, amp=AMP, extra=None):
    phase = 2 * np.pi * n / SPR + np.array([0.0, -np.pi / 2, 0.3, 0.3 - np.pi / 2])
    f = F0 + amp * np.cos(phase)
    return f if extra is None else f + extra


def _calibrated(config=None):
    config = config or MonitorConfig(SPR)
    bias = LoopBias(config, CHANNELS)
    end = int(config.calibration_revs) * SPR + 5 * SPR
    for n in range(end):
        bias.add(n, _force(n))
    bias.calibrate(end)
    return bias, end


def test_synchronous_force_averages_out_and_the_floor_is_the_threshold():
    bias, _ = _calibrated()
    # every mean equals F0 to rounding, so the healthy steps are ~0 and the floor rules
    np.testing.assert_allclose(bias.threshold, MonitorConfig(SPR).bias_floor)


def test_threshold_is_the_factor_over_the_largest_healthy_step():
    config = MonitorConfig(SPR)
    bias = LoopBias(config, CHANNELS)
    end = 40 * SPR
    for n in range(end):  # the mean alternates by +-15 N on b2x from revolution to revolution
        wobble = np.array([0.0, 0.0, 15.0 * (-1) ** (n // SPR), 0.0])
        bias.add(n, _force(n, extra=wobble))
    bias.calibrate(end)
    expected = np.full(4, config.bias_floor)
    expected[2] = config.bias_factor * 30.0
    np.testing.assert_allclose(bias.threshold, expected, rtol=1e-9)


def test_a_held_step_names_its_axis_with_its_size():
    bias, n0 = _calibrated()
    start = n0 + 7  # the episode's first sample, inside a revolution
    step = np.array([0.0, 0.0, 0.0, -55.0])
    for n in range(n0, start + 6 * SPR):
        bias.add(n, _force(n, amp=AMP * 1.3, extra=step if n >= start else None))
    axis, found = bias.step_at(start)
    assert axis == 3
    np.testing.assert_allclose(found, step, atol=1e-9 * AMP.max())


def test_no_step_for_a_synchronous_change_a_ring_down_or_a_small_step():
    bias, n0 = _calibrated()
    start = n0
    for n in range(n0, n0 + 6 * SPR):  # a mass loss: the 1 x amplitude doubles
        bias.add(n, _force(n, amp=2 * AMP))
    assert bias.step_at(start) is None
    bias, n0 = _calibrated()
    for n in range(n0, n0 + 6 * SPR):  # a ring-down of the mean, time constant 1.5 revolutions
        decay = np.array([400.0, 0.0, 0.0, 0.0]) * np.exp(-(n - n0) / (1.5 * SPR))
        bias.add(n, _force(n, extra=decay))
    assert bias.step_at(n0) is None
    bias, n0 = _calibrated()
    for n in range(n0, n0 + 6 * SPR):  # held, but below the 20 N floor
        bias.add(n, _force(n, extra=np.array([0.0, 19.0, 0.0, 0.0])))
    assert bias.step_at(n0) is None


def test_not_before_calibration_nor_without_revolutions_before_the_episode():
    bias = LoopBias(MonitorConfig(SPR), CHANNELS)
    for n in range(10 * SPR):
        bias.add(n, _force(n, extra=np.array([0.0, 0.0, 500.0 * (n > 5 * SPR), 0.0])))
    assert bias.threshold is None and bias.step_at(5 * SPR) is None
    bias, _ = _calibrated()
    assert bias.step_at(0) is None  # no revolution before it


def test_a_gap_starts_the_revolution_afresh():
    bias, n0 = _calibrated()
    start = n0 + 3 * SPR
    n = n0
    while n < start + 6 * SPR:
        if n == n0 + SPR + 5:
            n += 11  # 11 samples lost: the partial revolution is dropped, not averaged
        bias.add(n, _force(n, extra=np.array([60.0, 0.0, 0.0, 0.0]) if n >= start else None))
        n += 1
    axis, step = bias.step_at(start)
    assert axis == 0 and step[0] == pytest.approx(60.0, rel=1e-9)


def test_one_feedback_channel_per_axis():
    with pytest.raises(ValueError, match="one per bearing axis"):
        LoopBias(MonitorConfig(SPR), (2, 3, 4))


def _event(fault_type):
    from amb_common.faults import FaultEvent

    return FaultEvent(fault_type, 100, 110, 300, SPR, 180.0, plane=2, bearing=1,
                      evidence={"rule": "transient above 1 x in both frames"})  # fmt: skip


def test_revise_turns_a_contact_into_the_stepped_axis_probe_fault_only():
    from amb_common.faults import FaultType

    bias, n0 = _calibrated()
    step = np.array([0.0, -80.0, 0.0, 0.0])  # b1y
    for n in range(n0, n0 + 6 * SPR):
        bias.add(n, _force(n, extra=step))
    mask = np.ones(8, dtype=bool)
    ev = bias.revise(_event(FaultType.AUX_BEARING_CONTACT), n0, mask)
    assert (ev.fault_type, ev.channel, ev.plane, ev.bearing) == (FaultType.SENSOR_FAULT, 3, 2, 0)
    assert (ev.onset_sample_index, ev.detection_sample_index) == (100, 110)
    assert ev.severity == pytest.approx(80.0, rel=1e-9)
    assert ev.evidence["displacement_class"] == "AUX_BEARING_CONTACT"
    assert ev.evidence["force_axis"] == "b1y"
    mass_loss = _event(FaultType.MASS_LOSS)
    assert bias.revise(mass_loss, n0, mask) is mass_loss  # a latched rotor moves the 1 x level
    mask[3] = False  # the probe already reported
    assert bias.revise(_event(FaultType.AUX_BEARING_CONTACT), n0, mask).fault_type == (
        FaultType.AUX_BEARING_CONTACT
    )


def test_a_monitor_with_ki_but_no_feedback_channels_checks_coils_only():
    """FaultMonitor(config, ki): the coil check runs on the currents, the loop-bias check is
    off (it needs the probes the loop is fed from)."""
    from amb_fault_monitor.monitor import FaultMonitor

    ki = 572.0  # N/A, Table 2.2's current gain
    monitor = FaultMonitor(MonitorConfig(SPR), ki)
    demand = np.array([0.2, -0.1, 0.3, 0.5])  # A
    for n in range(4 * SPR):
        assert monitor.currents(n, ki * demand, demand, 180.0) == []
