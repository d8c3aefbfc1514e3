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
