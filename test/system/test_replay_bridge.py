"""The I/O bridge swap: filterbank, fault monitor and controller run unchanged on replay_bridge.

A run is recorded in-process (amb-sim), then played back by ``replay_bridge`` (a second
implementation of the plant's interface, real time) to the real filterbank, fault monitor and
controller nodes. The filterbank's coefficients equal those of the recording, and the bridge
receives exactly one command per measured period.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys

import pytest
import yaml
from msg_fill import diff, to_plain
from rosbags.rosbag2 import Reader

from amb_tools.bag_types import typestore

pytestmark = [pytest.mark.ros, pytest.mark.slow]

SPR = 32
SCENARIO = {
    "name": "replay",
    "speed": {"hz": 20.0},
    "duration": 1.0,
    "samples_per_rev": SPR,
    "measurement_noise": 2.0e-7,
    "events": [
        {"kind": "unbalance", "time": 0.0, "disk": "D1", "me": 0.5e-3, "angle": 0.0},
        {"kind": "mass_loss", "time": 0.5, "disk": "D1", "me": 4.3e-3, "angle": 0.0},
    ],
}


def _coefficients(bag) -> list:
    store = typestore()
    with Reader(bag) as reader:
        conns = [c for c in reader.connections if c.topic == "/amb/wavelet/coefficients"]
        return [store.deserialize_cdr(raw, c.msgtype) for c, _t, raw in reader.messages(conns)]


def test_nodes_run_unchanged_on_the_replay_bridge(tmp_path, node_process) -> None:
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(SCENARIO))
    sim = subprocess.run(
        [sys.executable, "-m", "amb_apps.sim_cli", "--scenario", str(scenario),
         "--controller", "none", "--out", str(tmp_path / "sim")],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert sim.returncode == 0, sim.stderr
    common = {"samples_per_rev": SPR}
    recorder = node_process(
        "recorder",
        params={"output": str(tmp_path / "replayed"), "topics": ["/amb/wavelet/*"],
                "stamp_source": "header"},
    )  # fmt: skip
    node_process("wavelet_filterbank", params=common)
    node_process("fault_monitor", params=common)
    node_process("wavelet_controller", params={**common, "controller": "none"})
    log = tmp_path / "commands.jsonl"
    bridge = node_process(
        "replay_bridge",
        params={"bag": str(tmp_path / "sim" / "bag"), "time_scale": 2.0,
                "command_log": str(log), "wait_for_subscribers": 4},
    )  # fmt: skip
    assert bridge.wait(120) == 0, bridge.log()
    assert recorder.stop(signal.SIGINT) == 0, recorder.log()
    n_periods = round(SCENARIO["duration"] * SCENARIO["speed"]["hz"])
    commands = [json.loads(line) for line in log.read_text().splitlines()]
    assert sorted(c["based_on_period"] for c in commands) == list(range(n_periods))
    assert all(c["period_index"] == c["based_on_period"] + 2 for c in commands)
    original = _coefficients(tmp_path / "sim" / "bag")
    replayed = _coefficients(tmp_path / "replayed")
    assert len(replayed) == len(original)
    for i, (a, b) in enumerate(zip(original, replayed, strict=True)):
        assert diff(to_plain(a), to_plain(b)) == [], f"coefficients[{i}]"
