"""The fault monitor beside the ACTIVE transient controller: faults of the probes it uses.

The wavelet controller (eq. 8.10, FE-route model) and the bearings' PID both close their loops
on the inner probes (planes 2 and 3), so a biased or noisy inner probe moves the rotor through
both. Issue 19 asks for sensor faults on those probes to be classified with and without the
transient controller active, and the outer probes too (planes 1 and 4: outside both loops by
default, the monitor's partner and plane checks alone); the monitor is fed as the node feeds it
(``amb_apps.closed_loop``).
The reference is the scenario: the faulty probe and its time.
"""

import numpy as np
import pytest

from amb_apps.closed_loop import fe_model, run_closed_loop
from amb_common.rig import load_rig
from amb_controller.config import ControllerConfig
from amb_fault_monitor.config import MonitorConfig
from amb_plant_sim.scenario import scenario_from_dict

SPR = 32
FAULT_TIME = 4.0003  # s: after the monitor's calibration (module docstring of the scenario)


def _scenario(rig, plane, axis, mode, value):
    return scenario_from_dict(
        {
            "name": f"in_loop_{mode}_{plane}{axis}",
            "speed": {"role": "first_critical"},
            "duration": 7.0,
            "samples_per_rev": SPR,
            "measurement_noise": 0.2e-6,
            "events": [
                {"kind": "unbalance", "time": 0.0, "disk": "D1", "me": 0.5e-3, "angle": 0.0},
                {"kind": "unbalance", "time": 0.0, "disk": "D4", "me": 0.5e-3, "angle": 2.0},
                {"kind": "sensor_fault", "time": FAULT_TIME, "plane": plane, "axis": axis,
                 "mode": mode, "value": value},
            ],
        },
        rig,
    )  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize(
    ("plane", "axis", "mode", "value", "channel"),
    [
        (2, "x", "offset", 2.0e-5, 2), (3, "y", "offset", 2.0e-5, 5), (2, "y", "noise", 3.0e-6, 3),
        (1, "x", "offset", 2.0e-5, 0), (4, "y", "noise", 3.0e-6, 7),  # outer probes
    ],
)  # fmt: skip
def test_inner_probe_fault_is_a_sensor_fault_with_the_controller_active(
    plane, axis, mode, value, channel
):
    rig = load_rig()
    scenario = _scenario(rig, plane, axis, mode, value)
    config = ControllerConfig(controller="transient", samples_per_rev=SPR)
    omega = 2 * np.pi * scenario.speed_hz
    result = run_closed_loop(rig, scenario, config, fe_model(rig, omega, config),
                             fault_monitor=True)  # fmt: skip
    assert not result.refused  # the controller was ACTIVE throughout
    events = [(e["fault_type"], e["channel"]) for e in result.fault_events]
    assert events == [("SENSOR_FAULT", channel)]
    onset = result.fault_events[0]["onset_sample_index"]
    fault = FAULT_TIME * scenario.speed_hz * SPR
    assert fault - SPR <= onset <= fault + SPR


@pytest.mark.slow
@pytest.mark.parametrize(("plane", "axis", "channel"), [(2, "x", 2), (3, "y", 5)])
def test_an_inner_probe_offset_is_provisionally_that_probe_with_the_controller_active(
    plane, axis, channel
):
    """With provisional classes (issue 19), the offset's jump names the probe within two
    revolutions of the fault (amb_fault_monitor.probe_jumps), and the decision confirms it."""
    rig = load_rig()
    scenario = _scenario(rig, plane, axis, "offset", 2.0e-5)
    config = ControllerConfig(controller="transient", samples_per_rev=SPR)
    omega = 2 * np.pi * scenario.speed_hz
    result = run_closed_loop(
        rig, scenario, config, fe_model(rig, omega, config), fault_monitor=True,
        monitor_config=MonitorConfig(SPR, provisional_revs=1.5),
    )  # fmt: skip
    assert not result.refused
    events = [
        (e["fault_type"], e["channel"], e["evidence"].get("status")) for e in result.fault_events
    ]
    assert events == [("SENSOR_FAULT", channel, "provisional"), ("SENSOR_FAULT", channel, "final")]
    fault = FAULT_TIME * scenario.speed_hz * SPR
    assert result.fault_events[0]["decision_sample_index"] - fault <= 2 * SPR
    assert result.fault_events[1]["evidence"]["revised"] is False
