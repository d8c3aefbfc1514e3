"""The monitor on synthetic rotor responses (scipy.signal.lsim two-mode model, synthetic.py).

Mass loss (a step in synchronous forcing, eq. 5.1) and a short contact impulse (eq. 5.5)
are detected and told apart with haar, db2 and db4 (the method does not depend on the
wavelet, section 5.2); sensor faults on one channel are isolated; healthy noisy running
gives no event.
"""

import numpy as np
import pytest
from synthetic import OMEGA, SPR, make_run, run_monitor

from amb_common.faults import FaultType
from amb_common.rig import load_rig
from amb_fault_monitor.config import MonitorConfig
from amb_fault_monitor.errors import FaultMonitorError, RecordError
from amb_fault_monitor.monitor import FaultMonitor
from amb_fault_monitor.records import CoefficientSet, SampleCoefficients
from amb_wavelet.filters import get_filters
from amb_wavelet.levels import support_length

WAVELETS = ("haar", "db2", "db4")
ONSET_REV = 30.3


def _true_onset() -> int:
    return int(np.ceil(ONSET_REV * SPR))


@pytest.mark.parametrize("wavelet", WAVELETS)
def test_healthy_noisy_run_gives_no_event(wavelet):
    xy, angle, idx = make_run(120, seed=5)
    monitor = FaultMonitor(MonitorConfig(SPR))
    assert run_monitor(monitor, xy, angle, idx, wavelet) == []
    assert monitor.calibrated


@pytest.mark.parametrize("wavelet", WAVELETS)
def test_mass_loss_detected_within_one_revolution(wavelet):
    xy, angle, idx = make_run(60, mass_loss_rev=ONSET_REV)
    events = run_monitor(FaultMonitor(MonitorConfig(SPR)), xy, angle, idx, wavelet)
    assert [e.fault_type for e in events] == [FaultType.MASS_LOSS]
    ev = events[0]
    true = _true_onset()
    assert 0 <= ev.detection_sample_index - true < SPR  # within one revolution
    # the onset lies inside the support of the level-R wavelet that saw the new 1 x level
    support_r = support_length(5, get_filters(wavelet).length)
    assert abs(ev.onset_sample_index - true) <= support_r
    assert ev.evidence["sync_ratio"] >= 1.5
    assert ev.omega == pytest.approx(OMEGA)


def test_haar_mass_loss_onset_within_one_finest_support():
    xy, angle, idx = make_run(60, mass_loss_rev=ONSET_REV)
    (ev,) = run_monitor(FaultMonitor(MonitorConfig(SPR)), xy, angle, idx, "haar")
    assert abs(ev.onset_sample_index - _true_onset()) <= support_length(1, 2)


@pytest.mark.parametrize("wavelet", WAVELETS)
def test_contact_detected_within_quarter_revolution(wavelet):
    xy, angle, idx = make_run(60, contact_rev=ONSET_REV)
    events = run_monitor(FaultMonitor(MonitorConfig(SPR)), xy, angle, idx, wavelet)
    assert [e.fault_type for e in events] == [FaultType.AUX_BEARING_CONTACT]
    true = int(ONSET_REV * SPR)
    assert 0 <= events[0].detection_sample_index - true <= SPR // 4
    assert events[0].count >= 1
    assert events[0].evidence["peak_ratio_above_1x_rotating"] > 1.0


def test_offset_on_one_channel_is_a_sensor_fault():
    xy, angle, idx = make_run(60)
    xy[int(ONSET_REV * SPR) :, 2] += 20e-6  # x2 offset by 20 um
    events = run_monitor(FaultMonitor(MonitorConfig(SPR)), xy, angle, idx)
    assert [(e.fault_type, e.channel, e.plane) for e in events] == [(FaultType.SENSOR_FAULT, 2, 2)]


def test_stuck_channel_is_a_sensor_fault_and_masked():
    xy, angle, idx = make_run(60)
    n0 = int(ONSET_REV * SPR)
    xy[n0:, 7] = xy[n0, 7]  # y4 stuck
    monitor = FaultMonitor(MonitorConfig(SPR))
    events = run_monitor(monitor, xy, angle, idx)
    assert [(e.fault_type, e.channel) for e in events] == [(FaultType.SENSOR_FAULT, 7)]
    assert events[0].evidence["mode"] == "stuck_or_zero"
    assert monitor.masked_channels == [7]
    assert events[0].detection_sample_index - n0 <= 2 * SPR


def test_reset_recalibrates():
    xy, angle, idx = make_run(40)
    monitor = FaultMonitor(MonitorConfig(SPR))
    run_monitor(monitor, xy, angle, idx)
    assert monitor.calibrated
    monitor.reset()
    assert not monitor.calibrated and monitor.masked_channels == []


def test_sample_index_must_increase():
    monitor = FaultMonitor(MonitorConfig(SPR))
    monitor.step(SampleCoefficients(5, OMEGA, ()))
    with pytest.raises(RecordError, match="must increase"):
        monitor.step(SampleCoefficients(5, OMEGA, ()))


def test_wrong_channel_count_is_refused():
    monitor = FaultMonitor(MonitorConfig(SPR))
    bad = CoefficientSet(1, "detail", "fixed", "even", 0, 0, 1, np.zeros(6), True)
    with pytest.raises(RecordError, match="expected 8"):
        monitor.step(SampleCoefficients(1, OMEGA, (bad,)))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"samples_per_rev": 24}, "power of two"), ({"frames": ("stator",)}, "frames"),
     ({"k": 0.0}, "k must be"), ({"isolation": 1.5}, "isolation")],
)  # fmt: skip
def test_config_errors(kwargs, match):
    args = {"samples_per_rev": SPR, **kwargs}
    with pytest.raises(FaultMonitorError, match=match):
        MonitorConfig(**args)


def test_plane_clearance_bearings_are_the_rigs_nearest_by_axial_position():
    """Rig.plane_clearance_bearings names, per sensor plane, the clearance bearing nearest it
    along the shaft in rig.yaml (1-based; on the Bath rig the outer planes' retainers R1 and
    R2, the inner planes' auxiliary bearings AB1 and AB2)."""
    rig = load_rig()
    zc = [c.z for c in rig.clearance_bearings]
    expected = tuple(1 + int(np.argmin([abs(z - s.z) for z in zc])) for s in rig.sensor_planes)
    assert rig.plane_clearance_bearings == expected
    kinds = [rig.clearance_bearings[b - 1].kind for b in expected]
    assert kinds == ["retainer", "auxiliary", "auxiliary", "retainer"]


def test_a_contact_event_names_the_clearance_bearing_of_its_plane():
    """The monitor takes the plane -> bearing map from the rig (here a made-up one, so that
    the number can only come from it); without it a contact's bearing is 0, not known."""
    xy, angle, idx = make_run(60, contact_rev=ONSET_REV)
    made_up = (7, 5, 6, 8)
    (ev,) = run_monitor(FaultMonitor(MonitorConfig(SPR), plane_bearings=made_up), xy, angle, idx)
    assert ev.fault_type == FaultType.AUX_BEARING_CONTACT
    assert ev.bearing == made_up[ev.plane - 1]
    (bare,) = run_monitor(FaultMonitor(MonitorConfig(SPR)), xy, angle, idx)
    assert bare.bearing == 0
