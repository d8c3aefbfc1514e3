"""fault_monitor over real DDS: measurements -> wavelet_filterbank -> fault_monitor -> events."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import pytest
from amb_msgs.msg import FaultEvent, Measurement
from diagnostic_msgs.msg import DiagnosticArray

from amb_wavelet.node import stream_qos

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "fault_monitor"))
from synthetic import HZ, SPR, make_run

pytestmark = pytest.mark.ros


def _measurement(i, xy, angle) -> Measurement:
    m = Measurement(sample_index=i, samples_per_rev=SPR, rotor_angle=float(angle))
    m.rotor_speed = 2 * math.pi * HZ
    m.displacement = xy
    m.header.stamp.sec = int(i / (SPR * HZ))
    m.header.stamp.nanosec = int((i / (SPR * HZ) % 1.0) * 1e9)
    return m


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
    assert ros.spin_until(
        lambda: pub.get_subscription_count() >= 2 and "messages" in diag, timeout=30.0
    ), (fb.log(), fm.log())
    xy, angle, idx = make_run(50, mass_loss_rev=30.3)
    for start in range(0, len(idx), 256):
        for i in range(start, min(start + 256, len(idx))):
            pub.publish(_measurement(int(idx[i]), xy[i], angle[i]))
        ros.spin_for(0.05)
    assert ros.spin_until(lambda: len(events) >= 1, timeout=30.0), (diag, fm.log())
    ev = events[0]
    assert ev.fault_type == FaultEvent.MASS_LOSS
    true = math.ceil(30.3 * SPR)
    assert 0 <= ev.detection_sample_index - true < SPR
    assert abs(int(ev.onset_sample_index) - true) <= 2
    keys = {kv.key for kv in ev.evidence}
    assert {"sync_ratio", "levels_crossed_rotating"} <= keys
    assert ros.spin_until(lambda: diag.get("events_logged") == "1", timeout=10.0), diag
    lines = log.read_text().splitlines()
    assert json.loads(lines[0])["fault_type"] == "MASS_LOSS"


def test_invalid_samples_per_rev_exits_with_configuration_error(node_process) -> None:
    fm = node_process("-m amb_fault_monitor.node", params={"samples_per_rev": 24})
    assert fm.wait(timeout=30.0) == 2
    assert "power of two" in fm.log()
