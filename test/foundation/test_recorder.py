"""The recorder node writes what it receives to a readable rosbag2 (real DDS, real bags)."""

from __future__ import annotations

import signal
from pathlib import Path

import numpy as np
import pytest
import yaml
from amb_msgs.msg import ControlCommand, FaultEvent, Measurement, WaveletCoefficients
from diagnostic_msgs.msg import DiagnosticArray
from msg_fill import diff, random_message, to_plain
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosbags.rosbag2 import Reader

from amb_tools.bag_types import typestore

pytestmark = pytest.mark.ros

QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=1000, reliability=ReliabilityPolicy.RELIABLE)
TOPICS = {
    "/amb/measurement": Measurement,
    "/amb/wavelet/coefficients": WaveletCoefficients,
    "/amb/control/command": ControlCommand,
    "/amb/fault/events": FaultEvent,
}
N = 40


def _record(ros, node_process, tmp_path: Path, stop_signal: int, stamp_source: str = "receive"):
    bag = tmp_path / "bag"
    params = tmp_path / "recorder.yaml"
    params.write_text(
        yaml.safe_dump(
            {
                "recorder": {
                    "ros__parameters": {
                        "output": str(bag),
                        "topics": ["/amb/*"],
                        "status_period": 0.2,
                        "stamp_source": stamp_source,
                    }
                }
            }
        )
    )
    recorder = node_process("recorder", params_file=params)
    node = ros.node("amb_test_publisher")
    pubs = {t: node.create_publisher(cls, t, QOS) for t, cls in TOPICS.items()}
    counts: dict[str, int] = {}

    def on_diagnostics(msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name == "recorder":
                counts.update({kv.key: int(kv.value) for kv in status.values})

    node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 10)
    subscribed = ros.spin_until(
        lambda: all(p.get_subscription_count() > 0 for p in pubs.values()), timeout=30.0
    )
    assert subscribed, f"recorder did not subscribe; its log:\n{recorder.log()}"

    rng = np.random.default_rng(11)
    sent = {t: [random_message(cls, rng) for _ in range(N)] for t, cls in TOPICS.items()}
    for msgs in sent.values():
        for msg in msgs:  # a stamp a rig could send: after 1970
            msg.header.stamp.sec = abs(msg.header.stamp.sec)
    for i in range(N):
        for topic, msgs in sent.items():
            pubs[topic].publish(msgs[i])
    written = ros.spin_until(lambda: all(counts.get(t) == N for t in TOPICS), timeout=30.0)
    assert written, f"recorder counts {counts}; its log:\n{recorder.log()}"
    code = recorder.stop(stop_signal)
    assert code == 0, recorder.log()
    assert "closed" in recorder.log()
    return bag, sent


@pytest.mark.parametrize("stop_signal", [signal.SIGTERM, signal.SIGINT])
def test_recorder_writes_every_message_and_closes_on_signal(
    ros, node_process, tmp_path, stop_signal
) -> None:
    bag, sent = _record(ros, node_process, tmp_path, stop_signal)
    store = typestore()
    got: dict[str, list] = {t: [] for t in TOPICS}
    with Reader(bag) as reader:
        assert next(bag.glob("*.mcap")).stat().st_size > 0
        for conn, _t, raw in reader.messages():
            got[conn.topic].append(store.deserialize_cdr(raw, conn.msgtype))
    for topic, msgs in sent.items():
        assert len(got[topic]) == N, topic
        for i, (a, b) in enumerate(zip(msgs, got[topic], strict=True)):
            assert diff(to_plain(a), to_plain(b)) == [], f"{topic}[{i}] differs in the bag"


def test_recorder_can_stamp_with_the_message_header(ros, node_process, tmp_path) -> None:
    bag, sent = _record(ros, node_process, tmp_path, signal.SIGTERM, stamp_source="header")
    with Reader(bag) as reader:
        stamps = {t: [] for t in TOPICS}
        for conn, t_ns, _raw in reader.messages():
            stamps[conn.topic].append(t_ns)
    for topic, msgs in sent.items():
        expected = sorted(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in msgs)
        assert sorted(stamps[topic]) == expected, topic


def test_recorder_refuses_an_existing_output_folder(node_process, tmp_path) -> None:
    recorder = node_process("recorder", params={"output": str(tmp_path)})
    assert recorder.wait(30) == 2
    assert "'output'" in recorder.log() and "exists" in recorder.log()


def _measurement(n: int, spr: int = 16) -> Measurement:
    m = Measurement(sample_index=n, samples_per_rev=spr, rotor_speed=2 * np.pi * 20.0)
    m.header.stamp.sec, m.header.stamp.nanosec = divmod(1_000_000_000 + n * 3_125_000, 10**9)
    m.displacement = [1e-6 * (n + c) for c in range(8)]
    return m


def test_recorder_in_a_namespace_records_the_resolved_names(ros, node_process, tmp_path) -> None:
    """Started in /rig_a, the recorder's default patterns (``amb/*``, ``/diagnostics``) and its
    relative ``topic_types`` resolve there: the bag holds ``/rig_a/amb/...``, not the root
    system's ``/amb/...``, and ``read_bag`` reads it back under the namespace it finds."""
    from amb_msgs.msg import ControllerStatus

    from amb_tools.bag_read import read_bag

    bag = tmp_path / "bag"
    recorder = node_process(
        "recorder",
        params={
            "output": str(bag),
            "status_period": 0.2,
            "stamp_source": "header",
            "topic_types": ["amb/control/status:amb_msgs/msg/ControllerStatus"],
        },
        extra_args=["-r", "__ns:=/rig_a"],
    )
    node = ros.node("amb_test_publisher")
    ours = {
        "/rig_a/amb/measurement": node.create_publisher(Measurement, "/rig_a/amb/measurement", QOS),
        "/rig_a/amb/control/status": node.create_publisher(
            ControllerStatus, "/rig_a/amb/control/status", QOS
        ),
    }
    other = node.create_publisher(Measurement, "/amb/measurement", QOS)  # a system at the root
    counts: dict[str, int] = {}

    def on_diagnostics(msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name == "rig_a/recorder":
                counts.update({kv.key: int(kv.value) for kv in status.values})

    node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 10)
    subscribed = ros.spin_until(
        lambda: all(p.get_subscription_count() > 0 for p in ours.values()), timeout=30.0
    )
    assert subscribed, f"recorder did not subscribe; its log:\n{recorder.log()}"
    # the root system's stream is seen in the graph but not recorded: wait for a discovery scan
    ros.spin_until(lambda: node.count_publishers("/amb/measurement") > 0, timeout=10.0)
    ros.spin_for(0.5)
    assert other.get_subscription_count() == 0, recorder.log()
    for n in range(N):
        ours["/rig_a/amb/measurement"].publish(_measurement(n))
        other.publish(_measurement(1000 + n))
    status = ControllerStatus(controller="transient", mode=ControllerStatus.MODE_ACTIVE)
    status.delay_periods, status.commands_sent = 2, N // 16
    ours["/rig_a/amb/control/status"].publish(status)
    expected = {"/rig_a/amb/measurement": N, "/rig_a/amb/control/status": 1}
    written = ros.spin_until(
        lambda: all(counts.get(t) == n for t, n in expected.items()), timeout=30.0
    )
    assert written, f"recorder counts {counts}; its log:\n{recorder.log()}"
    assert recorder.stop(signal.SIGINT) == 0, recorder.log()
    assert "recording ['/rig_a/amb/*', '/diagnostics']" in recorder.log()

    with Reader(bag) as reader:
        in_bag = {c.topic for c in reader.connections}
    assert {"/rig_a/amb/measurement", "/rig_a/amb/control/status"} <= in_bag
    assert not any(t.startswith("/amb/") for t in in_bag), in_bag

    data = read_bag(bag)
    assert data.namespace == "/rig_a"
    assert data.counts["/rig_a/amb/measurement"] == N
    assert data.measurements.sample_index.tolist() == list(range(N))
    assert data.controller["controller"] == "transient" and data.controller["commands_sent"] == 2
    assert data.missing == [
        "/rig_a/amb/wavelet/coefficients",
        "/rig_a/amb/control/command",
        "/rig_a/amb/fault/events",
    ]
    assert read_bag(bag, namespace="/rig_a").counts == data.counts
    # under another namespace the bag holds none of the streams
    assert read_bag(bag, namespace="/").measurements is None
