"""A starved controller falls behind the plant and catches up: its late commands do not wind it up.

Lock-step run of the mass loss at the first critical speed with the real plant, filterbank and
controller (transient, ACTIVE from a model file) over DDS. Once the controller has converged, its
process is starved for 4 s (it runs 5 ms in every 2.5 s, SIGSTOP / SIGCONT), as on a machine
whose CPU is taken by other jobs. The plant's watchdog takes the rotor to its PID and runs on at
the real-time pace; the commands the controller still makes reach it after their period has
started, and those periods run with zero wavelet force, flagged ``STATUS_COMMAND_MISSING``. The
controller must undo the steps that made them (``WaveletControlSupervisor.command_missing``):
otherwise its integrators wind up while the rotor sits on its PID, and the first command that
gets through throws it beyond the PID-only response (the failure of a loaded CI run of
``test_restart.py``: 0.76 mm at x2). Reference: the same scenario on PID alone (in process).

In some runs (two of five idle here on 2026-12-05, before the cure) the transport stops feeding
the starved controller's readers for good (docs/history.md, "A reader the transport stopped
feeding"). The controller then moves its two stream readers to a DDS participant of their own
(``amb_tools.reader_participant``: once no measurement has come for ``reader_renewal_after``
s while the plant's writer is matched) and must resume from there: the assertions below then
judge it as any other run. Only a run whose lock step never came back
while the controller was stale or blind (its ``/diagnostics``, its log) is reported as an
expected failure of the transport (issue 17) instead of a verdict on the controller, whose
wind-up is what the test is about.

With the controller blind to the flag (the old node) a starvation of this kind gave 0.91 /
0.92 mm at the end planes and 0.76 mm at the inner ones (x2, y2): 2.2-5.4 times PID alone.
"""

from __future__ import annotations

import numpy as np
import pytest
from amb_msgs.msg import ControllerStatus, Measurement
from reliability_helpers import Diagnostics, fe_model_file
from scenarios import SAMPLES_PER_REV, first_critical_mass_loss
from throttle import Throttle

from amb_apps.closed_loop import run_closed_loop
from amb_common.rig import load_rig
from amb_controller.config import ControllerConfig
from amb_controller.node import BLIND_READER
from amb_plant_sim.scenario import load_scenario
from amb_tools.streams import stream_qos

pytestmark = [pytest.mark.ros, pytest.mark.slow]

SPR = SAMPLES_PER_REV
# 16 s: after the 4 s starvation the controller works off its backlog at its own pace while the
# plant runs on at the real-time pace; in 12 s an idle fresh-clone run once caught up only at
# the last period (31 % of the periods controlled, against 66-67 % in three other runs)
SCENARIO = first_critical_mass_loss(16.0, name="starved_controller")


def test_a_starved_controller_does_not_wind_up(ros, node_process, tmp_path) -> None:
    scenario, model = fe_model_file(SCENARIO, tmp_path)
    node = ros.node("amb_test_starved_observer")
    samples: list[Measurement] = []
    statuses: list[ControllerStatus] = []
    qos = stream_qos(SPR)
    qos.depth = 1 << 16  # the observer keeps every sample even if the test process lags
    node.create_subscription(Measurement, "/amb/measurement", samples.append, qos)
    status_sub = node.create_subscription(
        ControllerStatus, "/amb/control/status", statuses.append, 1000
    )
    diagnostics = Diagnostics(node)
    node_process("wavelet_filterbank", params={"samples_per_rev": SPR})
    controller = node_process(
        "wavelet_controller",
        params={"samples_per_rev": SPR, "controller": "transient", "start_mode": "active",
                "model_file": str(model)},
    )  # fmt: skip
    assert ros.spin_until(lambda: status_sub.get_publisher_count() >= 1, 60.0), controller.log()
    # command_timeout: long enough that a controller slowed by a loaded machine (its first
    # command took over 0.1 s under a CPU hog) is waited for. The starvation below stops the
    # controller for 2.5 s at a time, longer than that timeout whatever the machine: with
    # 1 s stops (= the timeout) a loaded run once lost no command at all.
    plant = node_process(
        "plant_sim",
        params={"scenario_file": str(scenario), "samples_per_rev": SPR,
                "command_timeout": 1.0, "wait_for_subscribers": 3},
    )  # fmt: skip
    received = lambda: len(samples)  # noqa: E731
    # The starvation starts from the controller's own progress (its status, one small message a
    # period), not from the observer's count of samples: under a CPU hog the observer once lagged
    # the plant by ~3400 samples, the starvation began 14 periods before the end, and lock step
    # could not come back in time (a fail of the test's start, not of the controller).
    period = lambda: statuses[-1].period_index if statuses else -1  # noqa: E731
    assert ros.spin_until_progress(lambda: period() >= 35, period, stall=60.0), controller.log()
    starved_from = (period() + 1) * SPR
    throttle = Throttle(controller.proc.pid, on=0.005, period=2.5)
    throttle.start()
    try:
        ros.spin_for(4.0)
    finally:
        throttle.release()
    starved_to = len(samples)
    assert ros.spin_until_progress(lambda: plant.returncode is not None, received, stall=60.0)
    assert plant.returncode == 0, plant.log()
    # the observer may still be working off its backlog when the plant ends
    total = round(SCENARIO["duration"] * samples[0].rotor_speed / (2 * np.pi)) * SPR
    ros.spin_until_progress(lambda: len(samples) >= total, received, stall=10.0)

    assert [m.sample_index for m in samples] == list(range(total)), (
        f"the observer has {len(samples)} of {total} samples"
    )
    missing = [m.sample_index for m in samples if m.status & Measurement.STATUS_COMMAND_MISSING]
    # (a loaded machine may cost commands before the starvation too: the plant's watchdog at
    # work, which the controller must survive just the same)
    assert any(i >= starved_from - SPR for i in missing), "the starving cost commands"
    last_missing = max(missing)
    log = controller.log()
    report = diagnostics.values.get("wavelet_controller", {})
    if last_missing >= len(samples) - 10 * SPR:  # lock step never resumed: was it the transport?
        if BLIND_READER in log or (
            report.get("measurements_stale") == "True"
            and int(report.get("last_sample", "-1")) < len(samples) - 10 * SPR
        ):
            pytest.xfail(
                "issue 17: the transport stopped feeding the controller, and its readers' new "
                f"participant did not help (renewed {report.get('readers_renewed', '?')} times; "
                f"stale at sample {report.get('last_sample', '?')} of {len(samples)})"
            )
    assert last_missing < len(samples) - 10 * SPR, (
        f"lock step resumed before the end\ncontroller's /diagnostics: {report}\n{log}"
    )
    assert any(np.any(m.wavelet_force) for m in samples[last_missing + 1 :]), controller.log()

    rig = load_rig()
    resolved = load_scenario(scenario, rig)
    cfg = ControllerConfig(samples_per_rev=SPR, controller="none")
    pid = np.abs(run_closed_loop(rig, resolved, cfg).displacement).max(axis=0)
    x = np.array([m.displacement for m in samples])
    peak = np.abs(x).max(axis=0)
    assert np.all(peak <= 1.05 * pid), (
        f"peaks {peak * 1e6} um against PID alone {pid * 1e6} um (starved over samples "
        f"{starved_from}-{starved_to}, {len(missing)} samples without a command)"
    )
    end = np.abs(x[-5 * SPR :]).max(axis=0)
    assert np.all(end < 0.3 * pid), "converged again by the end"
    if int(report.get("readers_renewed", "0")) == 0:
        assert statuses[-1].commands_late > 0, "the controller counted its lost commands"
    # else its old readers lost the flagged samples of the starvation: it cannot have counted
    # them, and resumed from the new participant (lock step resumed, asserted above)
