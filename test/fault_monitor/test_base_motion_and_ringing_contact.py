"""Base motion by plane coherence below 1 x, and contacts inside a mass-loss ring-down.

Synthetic signals (synthetic.py, scipy.signal.lsim): base motion is a slow displacement in
phase on all four planes (eq. 3.6); the contact is a short radial impulse (eq. 5.5) added
while the response to a large mass loss (eq. 5.1) still rings. Reference values are the
closed-form coherence of known plane patterns and the known injection times.
"""

import numpy as np
import pytest
from synthetic import SPR, add_base_motion, make_run, run_monitor

from amb_common.faults import FaultType
from amb_fault_monitor.classifier import EpisodeEvidence, classify
from amb_fault_monitor.config import MonitorConfig
from amb_fault_monitor.episodes import Episode
from amb_fault_monitor.errors import FaultMonitorError
from amb_fault_monitor.monitor import FaultMonitor

WAVELETS = ("haar", "db2", "db4")
ONSET_REV = 30.3


@pytest.mark.parametrize("wavelet", WAVELETS)
@pytest.mark.parametrize(("axis", "hz"), [(0, 3.0), (1, 2.0)])
def test_slow_in_phase_motion_is_base_motion(wavelet, axis, hz):
    xy, angle, idx = make_run(100)
    xy = add_base_motion(xy, idx, start_rev=ONSET_REV, hz=hz, axis=axis)
    events = run_monitor(FaultMonitor(MonitorConfig(SPR)), xy, angle, idx, wavelet)
    assert [e.fault_type for e in events] == [FaultType.BASE_MOTION]
    ev = events[0]
    # gains (1, 0.8, 0.6, 1) along one axis: (sum g)^2 / (4 sum g^2) = 11.56 / 12.0
    assert ev.evidence["low_coherence"] == pytest.approx(11.56 / 12.0, abs=0.03)
    assert ev.evidence["low_dominance"] >= 2.0
    assert abs(ev.onset_sample_index - ONSET_REV * SPR) <= 1.5 * SPR


def test_same_motion_on_one_plane_only_is_not_base_motion():
    xy, angle, idx = make_run(100)
    xy = add_base_motion(xy, idx, start_rev=ONSET_REV, gains=(1.0, 0.0, 0.0, 0.0))
    events = run_monitor(FaultMonitor(MonitorConfig(SPR)), xy, angle, idx)
    assert events and FaultType.BASE_MOTION not in [e.fault_type for e in events]


@pytest.mark.parametrize(
    ("pattern", "expected"),
    [((1.0, 1.0, 1.0, 1.0), 1.0), ((1.0, -1.0, 1.0, -1.0), 0.0), ((1.0, 0.0, 0.0, 0.0), 0.25),
     ((1.0, 0.8, 0.6, 1.0), 11.56 / 12.0)],
)  # fmt: skip
def test_low_coherence_closed_form(pattern, expected):
    monitor = FaultMonitor(MonitorConfig(SPR))
    ep = Episode(start=0)
    for scale in (1.0, -2.0, 0.5):  # several coefficients, either sign
        delta = np.zeros(8)
        delta[0::2] = scale * np.asarray(pattern) * 1e-5
        ep.add_low_change(delta, monitor.channel_mask)
    assert ep.low_coherent / ep.low_energy == pytest.approx(expected, abs=1e-12)
    assert ep.low_peak == pytest.approx(2e-5)


def _evidence(low_coherence, low_peak, high_peak, sync_change):
    R = 5
    ratios = np.array([5.0, 4.0, 3.0, 6.0])
    return EpisodeEvidence(
        revolution_level=R,
        max_ratio={(6, "fixed"): ratios, (1, "fixed"): ratios, (1, "rotating"): ratios},
        channel_energy=np.ones(8),
        sync_ratio=np.zeros(4),
        sync_change=np.full(4, sync_change),
        low_coherence=low_coherence,
        low_peak=low_peak,
        high_peak=high_peak,
    )


@pytest.mark.parametrize(
    ("coh", "low", "high", "sync", "expected"),
    [(0.95, 40e-6, 8e-6, 1e-6, FaultType.BASE_MOTION),
     (0.50, 40e-6, 8e-6, 1e-6, FaultType.AUX_BEARING_CONTACT),  # planes not together
     (0.95, 12e-6, 13e-6, 1e-6, FaultType.AUX_BEARING_CONTACT),  # as much above 1 x
     (0.95, 40e-6, 8e-6, 30e-6, FaultType.AUX_BEARING_CONTACT)],  # 1 x moved as much
)  # fmt: skip
def test_base_motion_rule(coh, low, high, sync, expected):
    decision = classify(_evidence(coh, low, high, sync), MonitorConfig(SPR))
    assert decision.fault_type == expected


@pytest.mark.parametrize("wavelet", WAVELETS)
@pytest.mark.parametrize("after_revs", [2.0, 3.5])
def test_contact_inside_mass_loss_ringing(wavelet, after_revs):
    xy, angle, idx = make_run(80, mass_loss_rev=ONSET_REV, loss=1.5)
    contact_rev = ONSET_REV + after_revs
    hit, _, _ = make_run(80, contact_rev=contact_rev, unbalance=0.0, noise=0.0, contact=50.0)
    events = run_monitor(FaultMonitor(MonitorConfig(SPR)), xy + hit, angle, idx, wavelet)
    assert [e.fault_type for e in events] == [FaultType.MASS_LOSS, FaultType.AUX_BEARING_CONTACT]
    contact = events[1]
    true = int(contact_rev * SPR)
    assert 0 <= contact.detection_sample_index - true <= SPR // 4
    assert contact.count == 1
    assert contact.decision_sample_index >= events[0].decision_sample_index


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"decision_max_revs": 8.0}, "decision_max_revs"), ({"base_coherence": 1.5}, "base_coh"),
     ({"base_dominance": 0.0}, "base_dominance"), ({"rearm_revs": -1.0}, "rearm_revs")],
)  # fmt: skip
def test_new_config_errors(kwargs, match):
    with pytest.raises(FaultMonitorError, match=match):
        MonitorConfig(SPR, **kwargs)
