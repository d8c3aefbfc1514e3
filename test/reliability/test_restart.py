"""Restarts: the controller process is killed (SIGKILL) mid-run and started again.

Lock-step run of a mass loss at the first critical speed with the real plant, filterbank and
controller (transient, ACTIVE from a model file) over DDS. The controller is killed after the
fault: the plant's watchdog keeps the rotor on its PID (zero wavelet force, STATUS_WATCHDOG) and
the run goes on; a new controller process started with the same parameters loads the saved
model, re-enters ACTIVE, and its commands are applied again. Throughout, no displacement at
the inner (control) planes exceeds the 0.5 mm limit of the thesis (section 8.5.1) and the end
planes stay clear of the retainer bearings. Measured in this test's first runs: inner peaks
0.16-0.24 mm, end planes 0.55-0.66 mm (the wavelet force the dead controller was applying drops
to zero at once; PID alone peaks at ~0.40 mm at the end planes after this fault).

Under load the new controller's first commands can reach the plant too late (on its watchdog
the plant waits one period of real time for each). Those periods run on PID and are flagged
``STATUS_COMMAND_MISSING``; the controller must undo the steps that made them. It did not, once,
in a loaded CI run: its integrators wound up and the first command that got through threw the
rotor to 0.76 mm at x2 and 0.92 mm at the end planes (``test/closed_loop/test_lost_commands.py``
reproduces it in process).
"""

from __future__ import annotations

import signal

import numpy as np
import pytest
from amb_msgs.msg import ControllerStatus, Measurement
from reliability_helpers import fe_model_file, missing_runs
from scenarios import SAMPLES_PER_REV, first_critical_mass_loss

from amb_common.rig import load_rig
from amb_tools.cdr import read_measurement

pytestmark = [pytest.mark.ros, pytest.mark.slow]

SPR = SAMPLES_PER_REV
# room for the new process to start while the plant runs on its watchdog
SCENARIO = first_critical_mass_loss(30.0)
LIMIT = 0.5e-3  # m, thesis section 8.5.1
KILL_TIME = 3.0  # simulated s: 1.5 s after the mass loss


def stamp_s(msg: ControllerStatus | Measurement) -> float:
    """Simulated time a message is stamped with (s)."""
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def test_controller_killed_and_restarted_mid_run(ros, node_process, tmp_path) -> None:
    scenario, model = fe_model_file(SCENARIO, tmp_path)
    controller_params = {
        "samples_per_rev": SPR,
        "controller": "transient",
        "model_file": str(model),
        "start_mode": "active",
    }
    node = ros.node("amb_test_restart_observer")
    statuses: list[ControllerStatus] = []
    # The observer, in the test process, must keep up with the lock-step plant: raw CDR (read
    # after the run), every queued sample taken at each wake, a deep queue (1024 lost 338 of
    # 6208 in a loaded fresh-clone CI run), renewed if the transport stops feeding it
    # (ros_harness.StreamTap).
    tap = ros.tap(node, Measurement, "/amb/measurement", SPR)
    raw_samples = tap.raw
    status_sub = node.create_subscription(
        ControllerStatus, "/amb/control/status", statuses.append, 100
    )
    node_process("wavelet_filterbank", params={"samples_per_rev": SPR})
    first = node_process("wavelet_controller", params=controller_params)
    # statuses are volatile: be matched to the controller before the run starts
    assert ros.spin_until(lambda: status_sub.get_publisher_count() >= 1, 60.0), first.log()
    plant = node_process(
        "plant_sim",
        params={"scenario_file": str(scenario), "samples_per_rev": SPR,
                "command_timeout": 0.5, "wait_for_subscribers": 3},
    )  # fmt: skip
    # Let the controller act on the fault, then kill it. The kill is timed by the controller's
    # own statuses (one per period, stamped with the period's simulated time), not by the
    # observer's sample count: under load the observer's deep measurement queue lags the
    # lock-step plant by many revolutions, and a kill timed by it once came so late that the
    # plant finished the scenario before the new controller had started. The observer takes the
    # measurements as raw CDR (read after the run) so that it, and the statuses it reads, keep
    # up with the plant; a kill timed by statuses that lagged came 14 s late in a fresh-clone
    # run of the 20 s scenario, which is now 30 s long.
    assert ros.spin_until_progress(
        lambda: any(stamp_s(s) >= KILL_TIME for s in statuses), lambda: len(statuses)
    ), first.log() + plant.log()
    assert any(s.mode == ControllerStatus.MODE_ACTIVE for s in statuses), first.log()
    first.proc.send_signal(signal.SIGKILL)
    assert ros.spin_until(lambda: first.returncode is not None, 10.0)
    # the new process takes seconds to start: the plant runs those on its watchdog (PID only)
    n_status = len(statuses)
    second = node_process("wavelet_controller", params=controller_params)
    assert ros.spin_until(
        lambda: (
            any(s.mode == ControllerStatus.MODE_ACTIVE for s in statuses[n_status:])
            or plant.returncode is not None
        ),
        120.0,
    ), second.log()
    assert ros.spin_until_progress(
        lambda: plant.returncode is not None, lambda: len(raw_samples)
    ), plant.log()
    assert plant.returncode == 0, plant.log()
    ros.spin_for(0.5)

    samples = [read_measurement(r) for r in raw_samples]
    x = np.array([m.displacement for m in samples])
    # The plant ran the whole scenario. The observer is outside the loop: when the test process
    # is held longer than the plant's writer history (1024 samples) it loses the oldest ones
    # (38 of 6208 once, beside a colcon build and two test runs); the recorder's completeness is
    # tested in test_recorder_counts. A 1 % loss cannot hide an excursion that builds over
    # revolutions from the peak checks below. A reader the transport stopped feeding (renewed by
    # the harness) loses more (152 of 9344 in two runs of 31 and 121 beside a CPU hog): checked
    # last, an expected failure of issue 17's transport once the checks on what it saw held.
    total = round(SCENARIO["duration"] * samples[0].rotor_speed / (2 * np.pi)) * SPR
    index = np.array([m.sample_index for m in samples])
    assert index[-1] == total - 1 and np.all(np.diff(index) > 0), index
    lost = (
        f"the observer lost {total - len(samples)} of {total}: {missing_runs(index, total)}; "
        f"its reader renewed {tap.renewals} times"
    )
    peak = np.max(np.abs(x), axis=0)
    inner = peak[2:6]  # x2, y2, x3, y3: the planes beside the AMBs, where the PID acts
    assert np.all(inner < LIMIT), f"an inner plane left the 0.5 mm limit: peaks {peak}"
    # the end planes swing more (PID only peaks at ~0.40 mm there after this fault; the force
    # dropped at the kill adds to it): they must stay clear of the 900 um retainer bearings
    retainer = min(
        c.radial_clearance for c in load_rig().clearance_bearings if "retainer" in c.kind
    )
    assert np.all(peak < retainer), f"end planes reach the retainers: peaks {peak}"
    watchdog = [m for m in samples if m.status & Measurement.STATUS_WATCHDOG]
    assert watchdog and all(not np.any(m.wavelet_force) for m in watchdog)
    assert stamp_s(watchdog[0]) >= KILL_TIME, "the watchdog tripped before the kill"
    resumed = [s for s in statuses[n_status:] if s.mode == ControllerStatus.MODE_ACTIVE]
    assert resumed, second.log()
    last_watchdog = max(m.sample_index for m in watchdog)
    after = [m for m in samples if m.sample_index > last_watchdog]
    assert any(np.any(m.wavelet_force) for m in after), (
        f"commands were not applied again: {len(after)} samples after the watchdog; "
        f"statuses {[(s.period_index, s.mode, s.message) for s in statuses[n_status:]][:12]}"
        f"\n{plant.log()[-3000:]}"
    )
    assert "model" in second.log()
    if len(samples) < 0.99 * total and tap.renewals:  # checked last: the rest held on what it saw
        pytest.xfail(f"issue 17: the transport stopped feeding the test's observer: {lost}")
    assert len(samples) >= 0.99 * total, f"{lost}\n{plant.log()[-3000:]}"
