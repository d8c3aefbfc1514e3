"""The recorder loses nothing: a node crashes mid-run, the recorder is stopped, the bag holds
every message the publishers sent (lock-step, counts checked against the publishers' own)."""

from __future__ import annotations

import re
import signal

import pytest
import yaml
from rosbags.rosbag2 import Reader
from scenarios import steady_unbalance

pytestmark = [pytest.mark.ros, pytest.mark.slow]

SPR = 16
SCENARIO = steady_unbalance("recorder_counts", 3.0, SPR, measurement_noise=2.0e-7)


@pytest.mark.parametrize("stop_signal", [signal.SIGTERM, signal.SIGINT])
def test_bag_holds_every_message_after_a_crash_and_a_stop(
    ros, node_process, tmp_path, stop_signal
) -> None:
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(SCENARIO))
    bag = tmp_path / "bag"
    recorder = node_process(
        "recorder",
        params={"output": str(bag), "topics": ["/amb/measurement", "/amb/control/command"]},
    )
    filterbank = node_process("wavelet_filterbank", params={"samples_per_rev": SPR})
    controller = node_process(
        "wavelet_controller",
        params={"samples_per_rev": SPR, "controller": "none", "coefficient_timeout": 0.2},
    )
    node = ros.node("amb_test_observer")
    assert ros.spin_until(lambda: node.count_subscribers("/amb/control/command") >= 1, 30.0)
    plant = node_process(
        "plant_sim",
        params={"scenario_file": str(scenario), "samples_per_rev": SPR,
                "wait_for_subscribers": 3, "command_timeout": 5.0},
    )  # fmt: skip
    assert ros.spin_until(lambda: "samples/rev" in plant.log(), 60.0), plant.log()
    ros.spin_for(0.5)
    filterbank.proc.send_signal(signal.SIGKILL)  # a crash of another node mid-run
    assert ros.spin_until(lambda: plant.returncode is not None, 120.0), plant.log()
    assert plant.returncode == 0, plant.log()
    ros.spin_for(0.5)
    assert recorder.stop(stop_signal) == 0, recorder.log()
    controller.stop()

    n_samples = int(re.search(r"\((\d+) samples\)", plant.log()).group(1))
    applied = int(re.search(r"applied (\d+)", plant.log()).group(1))
    counts: dict[str, int] = {}
    with Reader(bag) as reader:
        for conn, _t, _raw in reader.messages():
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
    assert counts["/amb/measurement"] == n_samples == round(3.0 * 20.0) * SPR
    # one command per measured period; the plant applied all but the last `delay` of them
    assert counts["/amb/control/command"] == n_samples // SPR
    assert applied == n_samples // SPR - 2
    written = re.search(r"messages written: (.*)", recorder.log()).group(1)
    assert f"/amb/measurement: {n_samples}" in written


#: Lock-step run for a stopped recorder: long enough that the plant, left to run on, publishes
#: more than a writer's history (Fast DDS keeps 5000 of a KEEP_ALL writer's messages) past it,
#: however late the test stops the recorder. The test process sees the plant's first samples
#: late with one core busy; at 40 s (12800 samples, 4.8 s of wall at 8x real time) it stopped
#: the recorder with fewer than 5000 left in 2 of 20 runs, and the plant never waited.
HELD = {**SCENARIO, "name": "recorder_held", "duration": 120.0}
#: Samples the test sees before it stops the recorder: the loop under way, every reader long
#: matched.
STOP_AT = 1000
#: What the plant logs when it was held, by the recorder's transport: its history full (the
#: usual way), or, on shared memory, its write held by the stopped recorder's port
#: (amb_tools.lossless; 2 of 110 runs stopped 16 in). On UDP the recorder shares no lock with
#: the plant (amb_tools.transport_profile): only the history holds it.
HELD_LOGS = {
    "shm": ("publication waiting", "publication blocked"),
    "udp": ("publication waiting",),
}
#: The lock-step writers the recorder reads, by node: any of them may be the one held.
RECORDED_BY = {
    "plant_sim": ["/amb/measurement"],
    "wavelet_filterbank": ["/amb/wavelet/coefficients"],
    "wavelet_controller": ["/amb/control/command", "/amb/control/status"],
}


@pytest.mark.parametrize("transport", ["udp", "shm"])  # udp: as amb-run runs the recorder
def test_a_stopped_recorder_holds_the_lockstep_plant_and_loses_nothing(
    ros, node_process, tmp_path, transport
) -> None:
    """The demo's recorder, niced on two cores, once lost 240 of 18688 measurements: in
    lock-step the writers keep every message until each reader has it (amb_tools.lossless), so
    a recorder stopped mid-run holds the plant instead of missing what was overwritten."""
    from amb_msgs.msg import Measurement
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.serialization import deserialize_message
    from reliability_helpers import Diagnostics

    from amb_tools.lossless import WAITED_KEY
    from amb_tools.transport_profile import TRANSPORT_VARIABLE

    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(HELD))
    total = round(HELD["duration"] * HELD["speed"]["hz"]) * SPR
    bag = tmp_path / "bag"
    types = {
        "/amb/measurement": "amb_msgs/msg/Measurement",
        "/amb/wavelet/coefficients": "amb_msgs/msg/WaveletCoefficients",
        "/amb/control/command": "amb_msgs/msg/ControlCommand",
        "/amb/control/status": "amb_msgs/msg/ControllerStatus",
    }
    recorder = node_process(
        "recorder",
        params={"output": str(bag), "topics": [*types, "/diagnostics"],
                "topic_types": [f"{t}:{m}" for t, m in types.items()]},
        env={TRANSPORT_VARIABLE: transport},
    )  # fmt: skip
    filterbank = node_process("wavelet_filterbank", params={"samples_per_rev": SPR})
    controller = node_process(
        "wavelet_controller", params={"samples_per_rev": SPR, "controller": "none"}
    )
    node = ros.node("amb_test_held_observer")
    # the tap's silence during the deliberate hold is no deaf reader: a renewal then would lose
    # what the plant publishes before the new reader matches (56 samples, once, under load)
    tap = ros.tap(
        node, Measurement, "/amb/measurement", SPR, on_message=lambda raw: None, renew_after=30.0
    )
    # the recorder's readers matched by the writers themselves before the plant starts (as
    # amb-run's start gate waits): a reader the recorder, stopped at once, had not matched yet
    # got the coefficients only from its match on (5409 of 12800 samples in, in one suite)
    writers = Diagnostics(node)
    assert ros.spin_until(
        lambda: (
            writers.matched("wavelet_filterbank", "/amb/wavelet/coefficients") >= 2
            and writers.matched("wavelet_controller", "/amb/control/command") >= 1
            and writers.matched("wavelet_controller", "/amb/control/status") >= 1
        ),
        60.0,
    ), (writers.values, recorder.log(), filterbank.log(), controller.log())
    plant = node_process(
        "plant_sim",
        params={"scenario_file": str(scenario), "samples_per_rev": SPR,
                "wait_for_subscribers": 4, "command_timeout": 5.0},
    )  # fmt: skip
    assert ros.spin_until(lambda: tap.received >= STOP_AT, 60.0), plant.log()
    recorder.proc.send_signal(signal.SIGSTOP)
    try:
        at_stop = tap.received
        # the plant runs on until the writer's history is full of messages the recorder has not
        # acknowledged, then waits: no progress, and no end, while the recorder is stopped
        ended = ros.spin_until_progress(
            lambda: plant.returncode is not None, lambda: tap.received, stall=2.0, limit=120.0
        )
        held_at = tap.received
    finally:
        recorder.proc.send_signal(signal.SIGCONT)
    assert not ended and held_at < total, (at_stop, held_at, total, plant.log()[-2000:])
    # a write held by the port is logged once it returns, after the recorder runs again; on
    # shared memory the held write may be another writer's to the recorder (the filterbank's,
    # 1 of 4 CI suites: the plant then waited in lock-step for the command, not in a write)
    procs = {"plant_sim": plant, "wavelet_filterbank": filterbank, "wavelet_controller": controller}

    def held() -> list[str]:
        return [name for name, proc in procs.items()
                if any(text in proc.log() for text in HELD_LOGS[transport])]  # fmt: skip

    assert ros.spin_until(lambda: bool(held()), 10.0), (
        at_stop, held_at, plant.log()[-2000:], filterbank.log()[-2000:], controller.log()[-2000:]
    )  # fmt: skip
    if transport == "udp":  # only the history holds: the plant's fills first (a sample each)
        assert "plant_sim" in held(), plant.log()[-2000:]
    assert ros.spin_until_progress(
        lambda: plant.returncode is not None, lambda: tap.received, stall=30.0
    ), plant.log()[-2000:]
    assert plant.returncode == 0, plant.log()
    assert tap.received == total
    ros.spin_for(0.5)
    assert recorder.stop() == 0, recorder.log()
    controller.stop()
    filterbank.stop()

    counts: dict[str, int] = {}
    waited: dict[str, float] = {}  # the last report of each writer's waits, by topic
    with Reader(bag) as reader:
        for conn, _t, raw in reader.messages():
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
            if conn.topic == "/diagnostics":
                for status in deserialize_message(raw, DiagnosticArray).status:
                    waited |= {v.key: float(v.value) for v in status.values
                               if v.key.startswith(WAITED_KEY)}  # fmt: skip
    assert counts["/amb/measurement"] == total, counts
    assert counts["/amb/wavelet/coefficients"] == total // 2, counts  # one per two samples
    assert counts["/amb/control/command"] == total // SPR, counts  # one per measured period
    assert counts["/amb/control/status"] == total // SPR, counts
    for name in held():  # each held writer's own last report counts its wait
        assert max(waited.get(WAITED_KEY + t, 0.0) for t in RECORDED_BY[name]) > 0.0, waited
    if "plant_sim" in held():
        assert "measurements held" in plant.log(), plant.log()[-1500:]
