"""amb-report reads bags written by the real ``recorder`` node the same way as amb-sim's.

1. The amb-sim bag is replayed (its CDR bytes, in bag order) over DDS into the ``recorder``
   node with receive-time stamps, as ``ros2 bag record`` writes them: the report of that bag
   gives the same metrics as the report of the original.
2. (slow) ``amb-run``: the nodes as processes in a namespace (``--namespace /rig_b``), recorded
   by the recorder; the bag holds ``/rig_b/amb/...`` and its report gives the metrics ``amb-sim``
   computes in memory for the same scenario (the two runs are identical,
   ``test/system/test_lockstep_determinism.py``, which runs amb-run at the root namespace).
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosbags.rosbag2 import Reader
from scenarios import first_critical_mass_loss

from amb_apps import report_cli
from amb_apps.report_metrics import NOT_IN_BAG, bag_metrics, choose_fault_time
from amb_tools.bag_read import read_bag

pytestmark = pytest.mark.ros

QOS = QoSProfile(
    history=HistoryPolicy.KEEP_ALL, depth=10000, reliability=ReliabilityPolicy.RELIABLE
)


def _message_class(msgtype: str):
    import importlib

    pkg, _, name = msgtype.split("/")
    return getattr(importlib.import_module(f"{pkg}.msg"), name)


def _same_metrics(a: dict, b: dict, skip=("bag",)) -> None:
    assert set(a) == set(b)
    for key in a:
        if key not in skip:
            assert a[key] == b[key], key


@pytest.mark.slow
def test_bag_of_the_recorder_node_reads_like_the_original(
    ros, node_process, sim_wavelet, tmp_path
) -> None:
    src = sim_wavelet / "bag"
    bag = tmp_path / "recorded"
    params = tmp_path / "recorder.yaml"
    params.write_text(yaml.safe_dump({"recorder": {"ros__parameters": {
        "output": str(bag), "topics": ["/amb/*"], "status_period": 0.2,
        "stamp_source": "receive"}}}))  # fmt: skip
    recorder = node_process("recorder", params_file=params)
    node = ros.node("amb_report_replay")
    with Reader(src) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        raw = [(c.topic, bytes(data)) for c, _t, data in reader.messages()]
    pubs = {t: node.create_publisher(_message_class(m), t, QOS) for t, m in types.items()}
    counts: dict[str, int] = {}

    def on_diagnostics(msg) -> None:
        for status in msg.status:
            if status.name == "recorder":
                counts.update({kv.key: int(kv.value) for kv in status.values})

    from diagnostic_msgs.msg import DiagnosticArray

    node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 10)
    subscribed = ros.spin_until(
        lambda: all(p.get_subscription_count() > 0 for p in pubs.values()), timeout=30.0
    )
    assert subscribed, f"recorder did not subscribe; its log:\n{recorder.log()}"
    expected: dict[str, int] = {}
    for i, (topic, data) in enumerate(raw):
        pubs[topic].publish(data)
        expected[topic] = expected.get(topic, 0) + 1
        if i % 200 == 0:
            ros.spin_until(lambda: False, timeout=0.01)
    written = ros.spin_until(
        lambda: all(counts.get(t) == n for t, n in expected.items()), timeout=60.0
    )
    assert written, f"recorder counts {counts} != {expected}; log:\n{recorder.log()}"
    assert recorder.stop(signal.SIGINT) == 0, recorder.log()

    a, b = read_bag(src), read_bag(bag)
    assert a.counts == {t: n for t, n in b.counts.items() if t in a.counts}
    ma = bag_metrics(a, choose_fault_time(a), a.speed_hz())
    mb = bag_metrics(b, choose_fault_time(b), b.speed_hz())
    assert ma["fault_time_source"] == "first_fault_event"
    _same_metrics(ma, mb)
    out = tmp_path / "report"
    assert report_cli.main([str(bag), "--out", str(out)]) == 0
    for name in ("displacement", "coefficients_1x", "forces", "orbits", "fault_timeline"):
        assert (out / f"{name}.png").is_file(), name


SCENARIO = first_critical_mass_loss(2.0, 0.8, name="report_amb_run")


@pytest.mark.slow
def test_report_of_an_amb_run_bag_equals_amb_sim_metrics(tmp_path, ros_domain_id) -> None:
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(SCENARIO))
    sim = subprocess.run(
        [sys.executable, "-m", "amb_apps.sim_cli", "--scenario", str(scenario),
         "--controller", "none", "--out", str(tmp_path / "sim")],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert sim.returncode == 0, sim.stderr
    run = subprocess.run(
        [sys.executable, "-m", "amb_apps.run_cli", "--scenario", str(scenario),
         "--out", str(tmp_path / "run"), "--controller", "none", "--without", "fault_monitor",
         "--namespace", "/rig_b"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert run.returncode == 0, run.stdout + run.stderr
    assert "in namespace /rig_b" in run.stdout
    with Reader(tmp_path / "run" / "bag") as reader:
        recorded = {c.topic for c in reader.connections}
    assert "/rig_b/amb/measurement" in recorded
    assert not any(t.startswith("/amb/") for t in recorded), recorded
    out = tmp_path / "report"
    code = report_cli.main(
        [str(tmp_path / "run" / "bag"), "--scenario", str(scenario), "--out", str(out)]
    )
    assert code == 0
    ours = json.loads((out / "run" / "metrics.json").read_text())
    ref = json.loads((tmp_path / "sim" / "metrics.json").read_text())
    assert "/diagnostics" not in ours["bag_counts"]  # recorded, but not an /amb topic
    # the system's topics, under the run's namespace
    ours["bag_counts"] = {t.removeprefix("/rig_b"): n for t, n in ours["bag_counts"].items()}
    ours["missing_topics"] = [t.removeprefix("/rig_b") for t in ours["missing_topics"]]
    for key, value in ref.items():
        if key in NOT_IN_BAG or key in ("contact_source", "bag", "scenario"):
            continue
        assert ours[key] == value, key
    assert Path(out / "fault_timeline.png").is_file()
