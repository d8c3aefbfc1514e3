"""Command watchdog of plant_sim (lockstep) and run-time parameter refusal, over real DDS."""

from __future__ import annotations

import re

import numpy as np
import pytest
import yaml
from amb_msgs.msg import ControlCommand, Measurement
from reliability_helpers import Diagnostics, get_parameter, set_parameters

from amb_tools.conversions import to_float_array
from amb_tools.streams import COMMAND_QOS, stream_qos

pytestmark = [pytest.mark.ros, pytest.mark.slow]

SPR = 16
DELAY = 2
PERIODS = 16
SILENT = set(range(5, 9))  # the test controller does not answer for these target periods


def test_dead_controller_trips_the_watchdog_and_lockstep_resumes(ros, node_process, tmp_path):
    scenario = tmp_path / "s.yaml"
    scenario.write_text(
        yaml.safe_dump(
            {
                "name": "watchdog",
                "speed": {"hz": 20.0},
                "duration": PERIODS / 20.0,
                "events": [{"kind": "unbalance", "time": 0.0, "disk": "D1", "me": 1.0e-3}],
            }
        )
    )
    plant = node_process(
        "plant_sim",
        params={
            "scenario_file": str(scenario),
            "samples_per_rev": SPR,
            "delay_periods": DELAY,
            # a loaded machine's slow answers must not trip it; the silent periods must
            "command_timeout": 2.0,
            "status_period": 0.1,
        },
    )
    node = ros.node("amb_test_ctrl")
    pub = node.create_publisher(ControlCommand, "/amb/control/command", COMMAND_QOS)
    samples: list[Measurement] = []
    force = 10.0

    def on_measurement(m: Measurement) -> None:
        samples.append(m)
        if m.sample_index % SPR == SPR - 1:
            k = m.sample_index // SPR + DELAY
            if k in SILENT:
                return
            c = ControlCommand(period_index=k, start_sample_index=k * SPR, samples_per_period=SPR)
            c.delay_periods = DELAY
            c.based_on_period = k - DELAY
            c.header = m.header
            c.force = to_float_array(np.full(4 * SPR, force))
            pub.publish(c)

    node.create_subscription(Measurement, "/amb/measurement", on_measurement, stream_qos(SPR))
    diag = Diagnostics(node)
    lost_seen = []
    assert ros.spin_until(
        lambda: (
            lost_seen.append(diag.get("plant_sim", "controller_lost"))
            or len(samples) == PERIODS * SPR
        ),
        60.0,
    ), plant.log()
    assert plant.wait(60) == 0
    log = plant.log()
    # While the controller is lost the plant waits one period of real time for each command:
    # the first answer after the silence (for period 9, sent when period 7 is measured) makes
    # it unless the test process is slower than that (a loaded machine), then the next one does.
    resumed = re.search(r"commands resumed with period (\d+)", log)
    assert resumed and max(SILENT) < int(resumed[1]) <= max(SILENT) + 3, log
    late = set(range(max(SILENT) + 1, int(resumed[1])))
    by_period = [samples[k * SPR : (k + 1) * SPR] for k in range(PERIODS)]
    for k, period in enumerate(by_period):
        wf = np.array([m.wavelet_force for m in period])
        flags = [m.status for m in period]
        if k in SILENT | late:
            assert not wf.any(), k  # zero wavelet force in the first silent period already
            assert all(f & Measurement.STATUS_COMMAND_MISSING for f in flags), k
            # the watchdog flag until the first new command arrives (during 7 for period 9)
            if k < max(SILENT) + len(late):
                assert all(f & Measurement.STATUS_WATCHDOG for f in flags), k
        elif k >= DELAY:
            np.testing.assert_array_equal(wf, force)  # commands applied again after it
            assert not any(f & Measurement.STATUS_WATCHDOG for f in flags), k
    assert "True" in lost_seen, "the watchdog was not reported on /diagnostics"
    assert "controller lost" in log, log
    assert f"missing {len(SILENT | late)}," in log and "watchdog_trips 1" in log, log
    assert np.max(np.abs([m.displacement for m in samples])) < 0.5e-3  # on PID throughout


def test_run_time_parameters_are_validated_with_the_reason(ros, node_process) -> None:
    ctrl = node_process("wavelet_controller", params={"samples_per_rev": SPR})
    node = ros.node("amb_test_params")
    (bad,) = set_parameters(ros, node, "wavelet_controller", {"w": 1.5})
    assert not bad.successful and "'w'" in bad.reason and "1.5" in bad.reason, bad.reason
    assert "0 < w < 1" in bad.reason
    assert get_parameter(ros, node, "wavelet_controller", "w") == 0.75  # old value kept
    (bad_v,) = set_parameters(ros, node, "wavelet_controller", {"v": 1.0})
    assert not bad_v.successful and "'v'" in bad_v.reason
    (limit,) = set_parameters(ros, node, "wavelet_controller", {"force_limit": [2000.0] * 4})
    assert not limit.successful and "force_limit" in limit.reason and "1000" in limit.reason
    (ro,) = set_parameters(ros, node, "wavelet_controller", {"samples_per_rev": 32})
    assert not ro.successful and "samples_per_rev" in ro.reason, ro.reason
    results = set_parameters(ros, node, "wavelet_controller", {"w": 0.5, "gain": 0.1})
    assert all(r.successful for r in results), [r.reason for r in results]
    (fl,) = set_parameters(ros, node, "wavelet_controller", {"force_limit": [500.0] * 4})
    assert fl.successful, fl.reason
    assert get_parameter(ros, node, "wavelet_controller", "w") == 0.5
    (timeout,) = set_parameters(ros, node, "wavelet_controller", {"measurement_timeout": -1.0})
    assert not timeout.successful and "measurement_timeout" in timeout.reason
    assert ctrl.returncode is None, ctrl.log()
