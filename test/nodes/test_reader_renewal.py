"""The filterbank, the fault monitor, the recorder and the plant move their stream readers.

What they do when the transport stops feeding their readers while the writer runs on
(``amb_tools.reader_participant``; the starved controller of
``test/reliability/test_starved_controller.py`` and the lost observer of
``test_restart_filterbank_monitor.py``, docs/history.md), shown here with a writer that merely
pauses: after ``reader_renewal_after`` s without a measurement, its writer still matched, the
node's readers move to a node ``<name>_readers_1`` of a participant of their own, and the
stream that resumes is read from there to its last sample (a recorder's bag holds all of it).
Composed (``wavelet_stack``), the filterbank moves the reader the stack shares. The plant
watches its command reader the same way: a controller that stops answering while its writer
stays matched. The controller's case is in ``test_controller_node.py``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from amb_msgs.msg import ControlCommand, Measurement
from rclpy.serialization import deserialize_message
from reliability_helpers import Diagnostics, missing_runs, subscribed_by
from rosbags.rosbag2 import Reader

from amb_tools.conversions import to_float_array
from amb_tools.streams import COMMAND_QOS, stream_qos

pytestmark = pytest.mark.ros

SPR = 16
MOVED = "moved to a new participant"


def _measurement(index: int) -> Measurement:
    angle = 2 * math.pi * (index % SPR) / SPR
    m = Measurement(sample_index=index, samples_per_rev=SPR, rotor_angle=angle)
    m.rotor_speed = 2 * math.pi * 11.0
    m.displacement = 1e-5 * np.array([math.cos(angle + 0.3 * c) for c in range(8)])
    t = index / (SPR * 11.0)
    m.header.stamp.sec = int(t)
    m.header.stamp.nanosec = int((t % 1.0) * 1e9)
    return m


#: Each case: the executable, the status name whose readers move, how it reports its progress
#: (a /diagnostics key: the last sample processed, or for the recorder the count written).
CASES = {
    "wavelet_filterbank": ("wavelet_filterbank", "last_sample"),
    "fault_monitor": ("fault_monitor", "last_sample"),
    "recorder": ("recorder", "/amb/measurement"),
    # composed: the filterbank holds the measurement reader the stack shares; the recorder
    # composed with it takes the resumed stream in process from that reader
    "wavelet_stack": ("wavelet_filterbank", "last_sample"),
}


def _progress(diagnostics: Diagnostics, name: str, key: str, last: int) -> bool:
    value = diagnostics.get(name, key)
    return value == (str(last + 1) if key.startswith("/") else str(last))


@pytest.mark.parametrize("executable", list(CASES))
def test_a_silent_stream_with_its_writer_matched_moves_the_readers(
    ros, node_process, tmp_path, executable
) -> None:
    name, key = CASES[executable]
    bag = tmp_path / "bag"
    params = {"samples_per_rev": SPR, "reader_renewal_after": 1.0, "status_period": 0.2}
    if executable in ("recorder", "wavelet_stack"):
        params["output"] = str(bag)
    proc = node_process(executable, params=params)
    node = ros.node(f"amb_test_renewal_{executable}")
    diagnostics = Diagnostics(node)
    pub = node.create_publisher(Measurement, "/amb/measurement", stream_qos(SPR))
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0, 30.0), proc.log()
    ros.spin_for(0.5)  # the node's reader matched our writer (its own view may lag ours)

    def send(first: int, last: int) -> None:
        for i in range(first, last + 1):
            pub.publish(_measurement(i))

    send(0, 2 * SPR - 1)
    assert ros.spin_until(lambda: _progress(diagnostics, name, key, 2 * SPR - 1), 30.0), (
        diagnostics.values.get(name),
        proc.log(),
    )
    assert ros.spin_until(lambda: MOVED in proc.log(), 20.0), proc.log()
    moved_to = f"{name}_readers_1"
    assert ros.spin_until(
        lambda: (
            subscribed_by(node, "/amb/measurement", moved_to)
            and not subscribed_by(node, "/amb/measurement", name)
            and pub.get_subscription_count() == 1
        ),
        20.0,
    ), proc.log()
    ros.spin_for(1.0)  # our writer matches the new reader (its own view may lag the graph's)
    send(2 * SPR, 6 * SPR - 1)
    assert ros.spin_until(lambda: _progress(diagnostics, name, key, 6 * SPR - 1), 30.0), (
        diagnostics.values.get(name),
        proc.log(),
    )
    assert diagnostics.get(name, "readers_renewed") == "1"
    assert proc.log().count(MOVED) == 1, proc.log()
    if executable == "wavelet_stack":  # the composed recorder got the resumed stream too
        assert ros.spin_until(
            lambda: _progress(diagnostics, "recorder", "/amb/measurement", 6 * SPR - 1), 30.0
        ), (diagnostics.values.get("recorder"), proc.log())
    if "output" in params:  # nothing lost: the bag holds every sample published
        assert proc.stop() == 0, proc.log()
        with Reader(bag) as reader:
            indices = [
                deserialize_message(raw, Measurement).sample_index
                for conn, _t, raw in reader.messages()
                if conn.topic == "/amb/measurement"
            ]
        assert indices == list(range(6 * SPR)), indices


def test_the_plants_command_reader_moves_when_the_commands_stop_with_the_writer_matched(
    ros, node_process, tmp_path
) -> None:
    """Lock-step: the test's controller stops answering at period 4 and resumes once the plant's
    command reader has moved and matched the test's writer again (a new participant's discovery
    took ~2 s with one core busy: what is published before the match is lost)."""
    delay, duration = 2, 8.0  # the lost plant runs on at 20 periods/s meanwhile
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(
        yaml.safe_dump({"name": "renewal", "speed": {"hz": 20.0}, "duration": duration})
    )
    node = ros.node("amb_test_renewal_commander")
    diagnostics = Diagnostics(node)
    pub = node.create_publisher(ControlCommand, "/amb/control/command", COMMAND_QOS)
    samples: list[Measurement] = []
    silent = {"from": 4, "until": None}  # periods the test does not answer

    def answer(m: Measurement) -> None:
        samples.append(m)
        target = m.sample_index // SPR + delay
        if m.sample_index % SPR != SPR - 1:
            return
        if target >= silent["from"] and silent["until"] is None:
            return
        c = ControlCommand(period_index=target, start_sample_index=target * SPR)
        c.samples_per_period, c.delay_periods = SPR, delay
        c.force = to_float_array(np.zeros(4 * SPR))
        pub.publish(c)

    node.create_subscription(Measurement, "/amb/measurement", answer, stream_qos(SPR))
    plant = node_process(
        "plant_sim",
        params={"scenario_file": str(scenario), "samples_per_rev": SPR, "delay_periods": delay,
                "command_timeout": 0.2, "reader_renewal_after": 1.0, "status_period": 0.2},
    )  # fmt: skip
    assert ros.spin_until(lambda: MOVED in plant.log(), 30.0), plant.log()
    assert ros.spin_until(
        lambda: (
            subscribed_by(node, "/amb/control/command", "plant_sim_readers_1")
            and pub.get_subscription_count() == 1
        ),
        20.0,
    ), plant.log()
    silent["until"] = samples[-1].sample_index // SPR + delay
    n = int(duration * 20) * SPR
    assert ros.spin_until(lambda: len(samples) == n, 60.0), (len(samples), plant.log())
    assert plant.wait(30) == 0, plant.log()
    assert plant.log().count(MOVED) == 1, plant.log()
    assert diagnostics.get("plant_sim", "readers_renewed") == "1", diagnostics.values
    missing = {m.sample_index // SPR for m in samples if m.status & m.STATUS_COMMAND_MISSING}
    assert set(range(4, silent["until"] - 1)) <= missing, sorted(missing)
    # the commands come through the new reader: lock step resumed, the last periods controlled
    assert "commands resumed" in plant.log(), plant.log()
    assert not missing & set(range(n // SPR - 10, n // SPR)), (sorted(missing), plant.log())


def test_a_move_loses_nothing_and_writes_nothing_twice(ros, node_process, tmp_path) -> None:
    """The recorder's measurements pause beyond ``reader_renewal_after`` while its command
    stream runs on at 100 Hz: its readers move (the measurement writer stays matched), and the
    command reader, fed all along, hands over with messages queued on both its old and its new
    subscription. Every command is in the bag once and in order, and so is every measurement.
    (The move that destroyed the old reader before the new one matched lost what was published
    in between, stop 53: 56 samples of a test observer.)"""
    bag = tmp_path / "bag"
    proc = node_process(
        "recorder",
        params={"samples_per_rev": SPR, "reader_renewal_after": 1.0, "status_period": 0.2,
                "output": str(bag)},
    )  # fmt: skip
    node = ros.node("amb_test_renewal_handover")
    diagnostics = Diagnostics(node)
    measurements = node.create_publisher(Measurement, "/amb/measurement", stream_qos(SPR))
    commands = node.create_publisher(ControlCommand, "/amb/control/command", COMMAND_QOS)
    assert ros.spin_until(
        lambda: measurements.get_subscription_count() > 0 and commands.get_subscription_count() > 0,
        30.0,
    ), proc.log()
    ros.spin_for(0.5)  # the recorder's readers matched our writers (its own view may lag ours)
    sent = {"commands": 0}

    def command() -> None:
        c = ControlCommand(period_index=sent["commands"], samples_per_period=SPR)
        commands.publish(c)
        sent["commands"] += 1

    timer = node.create_timer(0.01, command)
    for i in range(2 * SPR):
        measurements.publish(_measurement(i))
    assert ros.spin_until(lambda: MOVED in proc.log(), 30.0), proc.log()
    ros.spin_for(0.5)
    for i in range(2 * SPR, 6 * SPR):
        measurements.publish(_measurement(i))
    node.destroy_timer(timer)
    written = ros.spin_until(
        lambda: (
            _progress(diagnostics, "recorder", "/amb/measurement", 6 * SPR - 1)
            and diagnostics.get("recorder", "/amb/control/command") == str(sent["commands"])
        ),
        30.0,
    )
    progress = (sent, diagnostics.values.get("recorder"))
    # stopped and read either way: the bag says which messages a short count lacks
    assert proc.stop() == 0, proc.log()
    recorded: dict[str, list[int]] = {"/amb/measurement": [], "/amb/control/command": []}
    with Reader(bag) as reader:
        for conn, _t, raw in reader.messages():
            if conn.topic == "/amb/measurement":
                recorded[conn.topic].append(deserialize_message(raw, Measurement).sample_index)
            elif conn.topic == "/amb/control/command":
                recorded[conn.topic].append(deserialize_message(raw, ControlCommand).period_index)
    assert recorded["/amb/measurement"] == list(range(6 * SPR)), (
        missing_runs(recorded["/amb/measurement"], 6 * SPR),
        proc.log(),
    )
    assert recorded["/amb/control/command"] == list(range(sent["commands"])), (
        missing_runs(recorded["/amb/control/command"], sent["commands"]),
        proc.log(),
    )
    assert written, (progress, proc.log())
    assert proc.log().count(MOVED) == 1, proc.log()
