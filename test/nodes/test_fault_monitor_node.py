"""fault_monitor over real DDS: measurements -> wavelet_filterbank -> fault_monitor -> events."""

from __future__ import annotations

import json
import math
import os
import signal

import late_command
import numpy as np
import pytest
from amb_msgs.msg import FaultEvent, Measurement
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from reliability_helpers import Diagnostics, get_parameter, set_parameters
from synthetic import HZ, SPR, make_run

from amb_common import topics
from amb_common.faults import FaultType
from amb_common.rig import load_rig
from amb_tools.streams import stream_qos

COEFFICIENTS = topics.absolute(topics.COEFFICIENTS)
EVENTS = topics.absolute(topics.FAULT_EVENTS)

pytestmark = pytest.mark.ros


def _measurement(i, xy, angle) -> Measurement:
    m = Measurement(sample_index=i, samples_per_rev=SPR, rotor_angle=float(angle))
    m.rotor_speed = 2 * math.pi * HZ
    m.displacement = xy
    m.header.stamp.sec = int(i / (SPR * HZ))
    m.header.stamp.nanosec = int((i / (SPR * HZ) % 1.0) * 1e9)
    return m


def _driver(ros, name: str, spr: int) -> tuple:
    """A test node publishing measurements and collecting events: (node, pub, events, diag)."""
    node = ros.node(name)
    pub = node.create_publisher(Measurement, "/amb/measurement", stream_qos(spr))
    events: list[FaultEvent] = []
    node.create_subscription(FaultEvent, "/amb/fault/events", events.append, 100)
    return node, pub, events, Diagnostics(node)


def _chain(ros, node_process, name: str, spr: int, monitor=None, **filterbank) -> tuple:
    """Filterbank (``filterbank``: more of its parameters) and monitor (``monitor``: more of
    its parameters) nodes and a driver, matched before samples flow: (node, pub, events, diag,
    filterbank, monitor)."""
    fb = node_process(
        "-m amb_wavelet.node",
        params={"wavelet": "haar", "samples_per_rev": spr, "levels": 6, **filterbank},
    )
    fm = node_process(
        "-m amb_fault_monitor.node",
        params={"samples_per_rev": spr, "status_period": 0.2, **(monitor or {})},
    )
    node, pub, events, diag = _driver(ros, name, spr)
    assert ros.spin_until(
        lambda: (
            pub.get_subscription_count() >= 2
            and diag.matched("wavelet_filterbank", COEFFICIENTS) >= 1
            and diag.matched("fault_monitor", EVENTS) >= 1
        ),
        timeout=30.0,
    ), (diag.values, fb.log(), fm.log())
    return node, pub, events, diag, fb, fm


def test_mass_loss_event_published_and_logged(ros, node_process, tmp_path) -> None:
    log = tmp_path / "events.jsonl"
    fb = node_process(
        "-m amb_wavelet.node", params={"wavelet": "haar", "samples_per_rev": SPR, "levels": 6}
    )
    fm = node_process(
        "-m amb_fault_monitor.node",
        params={"samples_per_rev": SPR, "event_log": str(log), "status_period": 0.2},
    )
    node = ros.node("amb_test_fm_driver")
    qos = stream_qos(SPR)
    pub = node.create_publisher(Measurement, "/amb/measurement", qos)
    events: list[FaultEvent] = []
    diag: dict[str, str] = {}
    node.create_subscription(FaultEvent, "/amb/fault/events", events.append, 100)

    def on_diag(msg: DiagnosticArray) -> None:
        for s in msg.status:
            if s.name == "fault_monitor":
                diag.update({kv.key: kv.value for kv in s.values})

    node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 10)
    writers = Diagnostics(node)
    # the filterbank's coefficients and the monitor's events matched to their readers (the
    # writers' own counts) before samples flow
    assert ros.spin_until(
        lambda: (
            pub.get_subscription_count() >= 2
            and writers.matched("wavelet_filterbank", COEFFICIENTS) >= 1
            and writers.matched("fault_monitor", EVENTS) >= 1
            and "messages" in diag
        ),
        timeout=30.0,
    ), (writers.values, fb.log(), fm.log())
    # the synthetic rotor starts at rest: its start-up transient lasts ~25 revolutions, which
    # the calibration waits out (stationarity test), so the loss comes after 50 revolutions
    xy, angle, idx = make_run(70, mass_loss_rev=50.3)
    for start in range(0, len(idx), 64):  # small bursts: best-effort streams drop under load
        for i in range(start, min(start + 64, len(idx))):
            pub.publish(_measurement(int(idx[i]), xy[i], angle[i]))
        ros.spin_for(0.05)
    assert ros.spin_until(lambda: len(events) >= 1, timeout=30.0), (diag, fm.log())
    ev = events[0]
    assert ev.fault_type == FaultEvent.MASS_LOSS
    true = math.ceil(50.3 * SPR)
    assert 0 <= ev.detection_sample_index - true < SPR, (diag, fm.log(), fb.log())
    assert abs(int(ev.onset_sample_index) - true) <= 2
    keys = {kv.key for kv in ev.evidence}
    assert {"sync_ratio", "levels_crossed_rotating"} <= keys
    assert ros.spin_until(lambda: diag.get("events_logged") == "1", timeout=10.0), diag
    lines = log.read_text().splitlines()
    assert json.loads(lines[0])["fault_type"] == "MASS_LOSS"


def test_a_provisional_class_is_published_before_the_final_one(ros, node_process) -> None:
    """provisional_revs (a ROS parameter): the synthetic mass loss's episode is published
    provisionally 1.5 revolutions after its onset, then decided; the final event names the
    provisional class it confirms or revises (issue 19)."""
    _, pub, events, _, fb, fm = _chain(
        ros, node_process, "amb_test_fm_provisional", SPR, monitor={"provisional_revs": 1.5}
    )
    xy, angle, idx = make_run(70, mass_loss_rev=50.3)
    for start in range(0, len(idx), 64):  # small bursts: best-effort streams drop under load
        for i in range(start, min(start + 64, len(idx))):
            pub.publish(_measurement(int(idx[i]), xy[i], angle[i]))
        ros.spin_for(0.05)
    assert ros.spin_until(lambda: len(events) >= 2, timeout=30.0), (fm.log(), fb.log())
    first, final = ({kv.key: kv.value for kv in e.evidence} for e in events[:2])
    assert first["status"] == "provisional", [e.description for e in events]
    true = math.ceil(50.3 * SPR)
    stamp = events[0].header.stamp  # the decision: the stamp of its sample (_measurement)
    decision = round((stamp.sec + stamp.nanosec * 1e-9) * SPR * HZ)
    assert 0 < decision - true <= 2 * SPR, (decision, true)
    assert final["status"] == "final"
    assert events[1].fault_type == FaultEvent.MASS_LOSS
    assert final["provisional_class"] == FaultType(events[0].fault_type).name
    assert final["revised"] == str(events[1].fault_type != events[0].fault_type)
    assert events[1].detection_sample_index == events[0].detection_sample_index


@pytest.mark.slow
def test_control_transient_is_counted_on_diagnostics_not_published(ros, node_process) -> None:
    """The soak's late command (late_command.py) with its wavelet force: a WARN, no event."""
    spr = late_command.SPR
    block, force = late_command.late_command_run(1.6, [70])  # zero force in period 70
    node, pub, events, diag, _, fm = _chain(ros, node_process, "amb_test_fm_control", spr)
    assert get_parameter(ros, node, "fault_monitor", "control_step") == 2.0
    assert get_parameter(ros, node, "fault_monitor", "tail_rise_median") == 3.0
    (refused,) = set_parameters(ros, node, "fault_monitor", {"control_step": 0.0})
    assert not refused.successful and "control_step" in refused.reason, refused.reason
    for start in range(0, block.sample_index.size, 64):  # small bursts, as above
        for i in range(start, min(start + 64, block.sample_index.size)):
            m = Measurement(sample_index=i, samples_per_rev=spr, rotor_angle=block.angle[i])
            m.rotor_speed = float(block.omega[i])
            m.displacement = block.displacement[i]
            m.wavelet_force = force[i]
            m.header.stamp.sec, m.header.stamp.nanosec = divmod(round(block.time[i] * 1e9), 10**9)
            pub.publish(m)
        ros.spin_for(0.05)
    counted = lambda: diag.get("fault_monitor", "control_transients") == "1"  # noqa: E731
    assert ros.spin_until(counted, timeout=60.0), (diag.values, fm.log())
    assert diag.levels["fault_monitor"] == int.from_bytes(DiagnosticStatus.WARN)
    assert diag.messages["fault_monitor"].startswith("transient from control action")
    assert "AUX_BEARING_CONTACT" in diag.get("fault_monitor", "last_control_transient")
    every = str(block.sample_index.size // 2)  # one coefficient message per second sample
    # a loaded monitor may still be working through the stream: wait while its count moves
    seen = lambda: diag.get("fault_monitor", "messages")  # noqa: E731
    assert ros.spin_until_progress(lambda: seen() == every, seen), (every, diag.values, fm.log())
    assert events == []


def test_invalid_samples_per_rev_exits_with_configuration_error(node_process) -> None:
    fm = node_process("-m amb_fault_monitor.node", params={"samples_per_rev": 24})
    assert fm.wait(timeout=30.0) == 2
    assert "power of two" in fm.log()


@pytest.mark.slow
def test_1x_trip_error_and_black_box_bag(ros, node_process, tmp_path) -> None:
    """A 1 x orbit growing from 20 to 80 um trips at 50 um (ERROR) and leaves a black-box bag."""
    from rosbags.highlevel import AnyReader

    from amb_tools.bag_types import typestore

    boxes = tmp_path / "blackbox"
    fb = node_process(
        "-m amb_wavelet.node", params={"wavelet": "haar", "samples_per_rev": SPR, "levels": 6}
    )
    fm = node_process(
        "-m amb_fault_monitor.node",
        params={
            "samples_per_rev": SPR,
            "status_period": 0.2,
            "trip_1x": 50e-6,
            "trip_displacement": 1e-3,
            "blackbox_dir": str(boxes),
            "blackbox_pre_s": 0.2,
            "blackbox_post_s": 0.1,
        },
    )
    node = ros.node("amb_test_fm_trip")
    pub = node.create_publisher(Measurement, "/amb/measurement", stream_qos(SPR))
    events: list[FaultEvent] = []
    planes: dict[str, tuple[int, dict]] = {}
    node.create_subscription(FaultEvent, "/amb/fault/events", events.append, 100)

    def on_diag(msg: DiagnosticArray) -> None:
        for s in msg.status:
            planes[s.name] = (s.level, {kv.key: kv.value for kv in s.values})

    node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 10)
    writers = Diagnostics(node)
    assert ros.spin_until(
        lambda: (
            pub.get_subscription_count() >= 2
            and writers.matched("wavelet_filterbank", COEFFICIENTS) >= 1
            and writers.matched("fault_monitor", EVENTS) >= 1
            and "fault_monitor" in planes
        ),
        timeout=30.0,
    ), (writers.values, fb.log(), fm.log())
    n_revs, step_rev = 40, 30
    for i in range(n_revs * SPR):
        theta = 2 * math.pi * i / SPR
        r = 20e-6 if i < step_rev * SPR else 80e-6
        xy = [0.0] * 8
        for p in range(4):
            xy[2 * p], xy[2 * p + 1] = r * math.cos(theta), r * math.sin(theta)
        pub.publish(_measurement(i, xy, theta % (2 * math.pi)))
        if i % 64 == 63:
            ros.spin_for(0.05)
    trips = lambda: [e for e in events if e.fault_type == FaultEvent.TRIP]  # noqa: E731
    assert ros.spin_until(lambda: len(trips()) >= 4, timeout=30.0), (events, fm.log())
    ev = trips()[0]
    ev_keys = {kv.key: kv.value for kv in ev.evidence}
    assert ev_keys["quantity"] == "1x"
    # the 1 x semi-major axis over the last revolution passes 50 um once more than 3/8 of the
    # revolution after the step carries the 80 um orbit: (50 - 20) / (80 - 20) = 1/2 rev
    true = step_rev * SPR
    assert true < ev.detection_sample_index <= true + SPR
    assert sorted(e.plane for e in trips()) == [1, 2, 3, 4]

    def settled_error() -> bool:
        level, values = planes.get("fault_monitor: plane 1", (0, {}))
        amp = float(values.get("amplitude_1x_m", 0.0))
        return level == DiagnosticStatus.ERROR and amp == pytest.approx(80e-6, rel=1e-5)

    # ERROR while tripped, with the 1 x amplitude of the 80 um orbit (diagnostics print 6 digits)
    assert ros.spin_until(settled_error, timeout=10.0), planes
    # black box: the bag of the first event, both topics, 0.2 s before to 0.1 s after
    # the folder appears when the bag opens; metadata.yaml when it is closed (post window over)
    assert ros.spin_until(lambda: any(boxes.glob("event_*/metadata.yaml")), 15.0), fm.log()
    bag = sorted(boxes.glob("event_*/metadata.yaml"))[0].parent
    with AnyReader([bag], default_typestore=typestore()) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        stamps = [t for c, t, _raw in reader.messages() if c.topic == "/amb/measurement"]
    assert set(counts) == {"/amb/measurement", "/amb/wavelet/coefficients"}
    fs = SPR * HZ
    span = (stamps[-1] - stamps[0]) * 1e-9
    assert span == pytest.approx(0.3, abs=3.0 / fs)
    assert counts["/amb/measurement"] == pytest.approx(0.3 * fs, abs=4)


def test_a_lost_coil_is_published_from_the_currents(ros, node_process) -> None:
    """Issue 19: the measured current of axis b2y reads 0 while 0.5 A is demanded from sample
    FAULT on: one COIL_FAILURE naming AMB 2 and b2y, a quarter revolution later, from the
    measurements alone (no coefficient stream); nothing before, nothing for the other axes."""
    ki = load_rig().amb.Ki  # N/A
    fm = node_process(
        "-m amb_fault_monitor.node", params={"samples_per_rev": SPR, "status_period": 0.2}
    )
    _, pub, events, writers = _driver(ros, "amb_test_fm_coil_driver", SPR)
    assert ros.spin_until(
        lambda: pub.get_subscription_count() >= 1 and writers.matched("fault_monitor", EVENTS),
        timeout=30.0,
    ), fm.log()
    fault, total = 40 * SPR, 44 * SPR  # the calibration window is 16 revolutions
    demand = np.array([0.2, -0.1, 0.3, 0.5])  # A per axis
    for start in range(0, total, 64):
        for i in range(start, min(start + 64, total)):
            m = _measurement(i, [0.0] * 8, 2 * math.pi * (i % SPR) / SPR)
            current = demand.copy()
            if i >= fault:
                current[3] = 0.0  # b2y: both coils lost
            m.bearing_force = (ki * demand).tolist()
            m.current = current.tolist()
            pub.publish(m)
        ros.spin_for(0.05)
    assert ros.spin_until(lambda: len(events) >= 1, timeout=30.0), fm.log()
    ros.spin_for(0.5)
    assert len(events) == 1, [e.description for e in events]
    ev = events[0]
    assert ev.fault_type == FaultEvent.COIL_FAILURE
    assert ev.bearing == 2
    assert {kv.key: kv.value for kv in ev.evidence}["axis"] == "b2y"
    assert ev.onset_sample_index == fault
    assert ev.detection_sample_index == fault + math.ceil(0.25 * SPR) - 1


@pytest.mark.slow
def test_an_offset_probe_inside_the_loop_is_published_as_a_sensor_fault(ros, node_process):
    """Issue 19: the suite's 20 um offset on the plane-2 x probe at 28.65 Hz (the PID's own
    probe), simulated by the plant core and replayed over DDS with its currents and commanded
    forces: the monitor node names channel 2, not the contact its displacements alone read
    (amb_fault_monitor.loop_bias, fed the rig's feedback channels by the node)."""
    from pathlib import Path

    from amb_apps.evaluation import simulate_case

    suite = Path(__file__).resolve().parents[2] / "config" / "scenarios" / "faults"
    case = simulate_case(suite / "sensor_offset_plane2x_29hz.yaml", load_rig())
    block, spr = case.block, case.samples_per_rev
    _, pub, events, _, fb, fm = _chain(ros, node_process, "amb_test_fm_offset_driver", spr)
    n = block.sample_index.size
    for start in range(0, n, 64):  # small bursts: best-effort streams drop under load
        for i in range(start, min(start + 64, n)):
            t = float(block.time[i])
            m = Measurement(sample_index=int(block.sample_index[i]), samples_per_rev=spr)
            m.rotor_angle = float(block.angle[i])
            m.rotor_speed = float(block.omega[i])
            m.displacement = block.displacement[i].tolist()
            m.bearing_force = block.bearing_force[i].tolist()
            m.current = block.current[i].tolist()
            m.header.stamp.sec = int(t)
            m.header.stamp.nanosec = int((t % 1.0) * 1e9)
            pub.publish(m)
        ros.spin_for(0.05)
    assert ros.spin_until(lambda: len(events) >= 1, timeout=30.0), (fm.log(), fb.log())
    ros.spin_for(0.5)
    ev = events[0]
    assert (ev.fault_type, ev.channel, ev.plane) == (FaultEvent.SENSOR_FAULT, 2, 2), [
        e.description for e in events
    ]
    fault = 2.0 * case.speed_hz * spr  # the scenario's fault time, in samples
    assert abs(int(ev.onset_sample_index) - fault) <= spr
    assert FaultEvent.AUX_BEARING_CONTACT not in {e.fault_type for e in events}


def test_the_last_coefficients_after_the_filterbanks_catch_up_are_processed(
    ros, node_process
) -> None:
    """The filterbank stopped while the stream goes on catches up (``max_backlog`` 1) and the
    stream ends there: its last coefficient message jumps past the ones it never computed. The
    monitor's own reader lost nothing, but the message says the filterbank restarted its
    filters (level 1 not settled), so the jump is the filterbank's gap and is processed, not
    held for a confirmation that never comes (``amb-run``'s drain waited 300 s for it)."""
    xy, angle, idx = make_run(6)
    n = idx.size
    _, pub, _, diag, fb, fm = _chain(
        ros, node_process, "amb_test_fm_fb_catch_up", SPR, max_backlog=1, status_period=0.2
    )
    last = lambda: diag.get("fault_monitor", "last_coefficient_sample")  # noqa: E731
    first = 2 * SPR
    for i in range(first):
        pub.publish(_measurement(int(idx[i]), xy[i], angle[i]))
        ros.spin_for(0.002)
    assert ros.spin_until(lambda: last() == str(first - 1), 30.0), (diag.values, fm.log())
    os.kill(fb.proc.pid, signal.SIGSTOP)
    try:
        for i in range(first, n):
            pub.publish(_measurement(int(idx[i]), xy[i], angle[i]))
            ros.spin_for(0.001)
        ros.spin_for(0.5)
    finally:
        os.kill(fb.proc.pid, signal.SIGCONT)
    assert ros.spin_until(lambda: last() == str(n - 1), 20.0), (diag.values, fm.log(), fb.log())
    # On resume the stopped filterbank may find its queue filled in more than one burst (a
    # loaded machine), each burst a catch-up and a reset: the monitor's gaps are the
    # filterbank's resets, one or more, and none of its own reader's making. A reset at an even
    # sample index followed by the next before the odd one (level 1 completes on odd indices)
    # publishes nothing in between, so the monitor sees the two as one jump (one core busy,
    # 2026-12-03: 2 resets, 1 gap).
    assert ros.spin_until(
        lambda: diag.get("wavelet_filterbank", "last_sample") == str(n - 1), 10.0
    ), (diag.values, fb.log())
    resets = int(diag.get("wavelet_filterbank", "gaps_reset"))
    assert resets >= 1, (diag.values, fb.log())
    gaps = int(diag.get("fault_monitor", "coefficients_gap"))
    assert 1 <= gaps <= resets, (diag.values, fm.log())
    assert diag.get("fault_monitor", "backlog_dropped") == "0", diag.values
    assert diag.get("fault_monitor", "last_sample") == str(n - 1), diag.values
