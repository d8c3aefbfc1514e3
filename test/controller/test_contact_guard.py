"""
The contact guard: a controller stops when a probe reads the clearance of the auxiliary bearing
next to it (``ControllerConfig.contact_guard``, :func:`amb_controller.guard.controller_guard`).

References: the clearance bearings and sensor planes of ``config/rig.yaml`` read by hand (0.75
mm auxiliary bearings inside the magnets, thesis section 2.1; the retainers at the shaft's
ends, where the outer probes sit, are not auxiliary bearings); the simulator's own contact
truth and PID alone on the same scenario for the closed loop.
"""

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from amb_apps.closed_loop import fe_model, run_closed_loop
from amb_common.paths import config_file
from amb_common.rig import load_rig
from amb_controller.config import ControllerConfig
from amb_controller.errors import ControllerValueError
from amb_controller.guard import DivergenceGuard, GuardConfig
from amb_controller.selection import controller_guard
from amb_plant_sim.scenario import load_scenario

AUX = 750.0e-6  # m, auxiliary bearings AB1, AB2 (rig.yaml clearance_bearings)


def test_the_inner_probes_take_the_clearance_of_the_auxiliary_bearing_next_to_them():
    # S1 at z = 2.0 (nearest R1, a retainer), S2 at 1.3799 (AB1 at 1.4199), S3 at 0.6221 (AB2 at
    # 0.5819), S4 at 0 (R2)
    expected = (math.inf,) * 2 + (AUX,) * 4 + (math.inf,) * 2
    np.testing.assert_allclose(load_rig().probe_clearance, expected, rtol=1e-12)


def test_the_guard_trips_at_a_probe_s_own_clearance_only():
    guard = DivergenceGuard(
        GuardConfig(probe_clearance=(math.inf,) * 2 + (AUX,) * 4 + (math.inf,) * 2)
    )
    peaks = np.full(8, 0.1e-3)
    peaks[0] = 0.95e-3  # an outer probe: at its retainer (0.9 mm), no auxiliary bearing
    assert not guard.update(np.zeros(2), displacement_peak=peaks)
    peaks[3] = 0.76e-3  # an inner probe past the auxiliary bearing's clearance
    assert guard.update(np.zeros(2), displacement_peak=peaks)
    assert "probe channel 3" in guard.reason and "clearance" in guard.reason
    guard.reset()
    assert not guard.update(np.zeros(2), displacement_peak=0.8e-3)  # overall: no probe check
    with pytest.raises(ControllerValueError, match="4 probe peaks for 8"):
        guard.update(np.zeros(2), displacement_peak=np.full(4, 0.1e-3))


def test_controller_guard_checks_the_probes_only_with_contact_guard():
    clearance = (AUX,) * 8
    on = controller_guard(ControllerConfig(), clearance)
    off = controller_guard(ControllerConfig(contact_guard=False), clearance)
    assert on.config.probe_clearance == clearance
    assert off.config.probe_clearance is None
    assert controller_guard(ControllerConfig(), None).config.probe_clearance is None


@pytest.mark.slow
def test_the_thesis_controller_at_delay_2_ends_no_worse_than_pid_in_the_contact_case():
    """Thesis figure 5.27 case 2 (516 g cm lost at 19 Hz): PID alone ends on the auxiliary
    bearings. The eq.-8.10 controller at i = 2 keeps integrating once the rotor touches and
    bounces it from contact to contact (measured with the guard off: 91 contact onsets against
    PID's 24, amb-compare of 2026-12-04); with the guard it stops at the first reading of the
    clearance and ends with no more onsets and no higher inner peak than PID alone."""
    rig = load_rig()
    scenario = load_scenario(Path(config_file("scenarios/mass_loss_contact_case2.yaml")), rig)
    base = ControllerConfig(
        samples_per_rev=scenario.samples_per_rev,
        controller="transient",
        delay_periods=2,
        w=0.75,
        v=0.75,
        gain=0.5,
        inverse_order=5,
        force_limit=(rig.amb.force_limit,) * 4,
    )  # amb-compare's wavelet_i2
    model = fe_model(rig, 2 * math.pi * scenario.speed_hz, base)

    def outcome(config, model):
        run = run_closed_loop(rig, scenario, config, model)
        spr = run.samples_per_rev
        after = round(run.fault_time * scenario.speed_hz) * spr
        touching = run.contact.any(axis=1).astype(int)
        onsets = int(np.count_nonzero(np.diff(touching, prepend=0) == 1))
        inner = float(np.abs(run.displacement[after:, rig.feedback_channels]).max())
        return run, onsets, inner

    _, pid_onsets, pid_peak = outcome(replace(base, controller="none"), None)
    guarded, onsets, peak = outcome(base, model)
    assert pid_onsets > 0  # the case: PID alone touches
    assert onsets <= pid_onsets and peak <= pid_peak, (onsets, pid_onsets, peak, pid_peak)
    assert guarded.commands[-1].guard_tripped
    _, free_onsets, _ = outcome(replace(base, contact_guard=False), model)
    assert free_onsets > pid_onsets  # without the guard: what it prevents
