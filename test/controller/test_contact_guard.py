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
RETAINER = 900.0e-6  # m, bronze retainers R1, R2 (the same)


def test_the_inner_probes_take_the_clearance_of_the_auxiliary_bearing_next_to_them():
    # S1 at z = 2.0 (nearest R1, a retainer), S2 at 1.3799 (AB1 at 1.4199), S3 at 0.6221 (AB2 at
    # 0.5819), S4 at 0 (R2)
    expected = (math.inf,) * 2 + (AUX,) * 4 + (math.inf,) * 2
    np.testing.assert_allclose(load_rig().probe_clearance, expected, rtol=1e-12)


def test_the_outer_probes_read_against_the_retainers_next_to_them():
    """The early action's check (every clearance bearing, the retainers too): S1 and S4 at the
    shaft's ends by the bronze retainers, 0.9 mm (rig.yaml clearance_bearings)."""
    expected = (RETAINER,) * 2 + (AUX,) * 4 + (RETAINER,) * 2
    np.testing.assert_allclose(load_rig().probe_nearest_clearance, expected, rtol=1e-12)


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


def _onsets(run) -> int:
    """Contact onsets of a run (simulator truth)."""
    touching = run.contact.any(axis=1).astype(int)
    return int(np.count_nonzero(np.diff(touching, prepend=0) == 1))


def _wavelet_i2(rig, scenario, **kw) -> ControllerConfig:
    """amb-compare's wavelet_i2 settings for ``scenario`` (``kw`` changes fields)."""
    return ControllerConfig(
        samples_per_rev=scenario.samples_per_rev,
        controller="transient",
        delay_periods=2,
        w=0.75,
        v=0.75,
        gain=0.5,
        inverse_order=5,
        force_limit=(rig.amb.force_limit,) * 4,
        **kw,
    )


@pytest.mark.slow
def test_the_thesis_controller_at_delay_2_ends_no_worse_than_pid_in_the_contact_case():
    """Thesis figure 5.27 case 2 (516 g cm lost at 19 Hz): PID alone ends on the auxiliary
    bearings. The eq.-8.10 controller at i = 2, guard on, ends with no more contact onsets and
    no higher inner peak than PID alone (measured on the current rig: it keeps the rotor clear,
    0 onsets and 368 um against PID's 50 and 860 um; the guard has nothing to stop there: what
    it stops is in the test below)."""
    rig = load_rig()
    scenario = load_scenario(Path(config_file("scenarios/mass_loss_contact_case2.yaml")), rig)
    base = _wavelet_i2(rig, scenario)
    model = fe_model(rig, 2 * math.pi * scenario.speed_hz, base)

    def outcome(config, model):
        run = run_closed_loop(rig, scenario, config, model)
        after = round(run.fault_time * scenario.speed_hz) * run.samples_per_rev
        inner = float(np.abs(run.displacement[after:, rig.feedback_channels]).max())
        return _onsets(run), inner

    pid_onsets, pid_peak = outcome(replace(base, controller="none"), None)
    onsets, peak = outcome(base, model)
    assert pid_onsets > 0  # the case: PID alone touches
    assert onsets <= pid_onsets and peak <= pid_peak, (onsets, pid_onsets, peak, pid_peak)


@pytest.mark.slow
def test_the_guard_stops_a_loop_that_drives_the_rotor_into_contact_at_the_first_reading():
    """A loop that diverges: the 150 N step scenario at the third critical speed with the outer
    probes and a first-order inverse (wavelet_i2 settings otherwise; radius 1.068 on its own
    model, its model check off so that it runs; test/beyond/test_third_critical.py). PID alone
    touches nothing there. Reference: the simulator's displacement and contact truth. The
    guard trips on the period whose probe reading first reaches the clearance and the force
    is zero from the period that command is for; without the guard the controller keeps
    pushing (a force to the run's end) and bounces the rotor from contact to contact (measured
    71 onsets against 15 with the guard, over 2 s)."""
    rig = load_rig()
    scenario = load_scenario(
        Path(config_file("scenarios/sync_force_150N_third_critical.yaml")), rig
    )
    scenario = replace(scenario, duration=2.0)
    base = _wavelet_i2(rig, scenario, sensors=(0, 1, 6, 7), max_model_radius=math.inf)
    base = replace(base, inverse_order=1)
    model = fe_model(rig, 2 * math.pi * scenario.speed_hz, base)
    assert _onsets(run_closed_loop(rig, scenario, replace(base, controller="none"))) == 0

    guarded = run_closed_loop(rig, scenario, base, model)
    spr = guarded.samples_per_rev
    reached = np.abs(guarded.displacement) >= np.array(rig.probe_clearance)
    first = int(np.flatnonzero(reached.any(axis=1))[0]) // spr  # period of the first reading
    trip = next(c for c in guarded.commands if c.guard_tripped)
    assert trip.based_on_period == first
    assert not np.any(guarded.wavelet_force[trip.target_period * spr :])

    free = run_closed_loop(rig, scenario, replace(base, contact_guard=False), model)
    assert not any(c.guard_tripped for c in free.commands)
    assert np.abs(free.wavelet_force[-spr:]).max() > 0.0
    assert _onsets(free) > _onsets(guarded) > 0
