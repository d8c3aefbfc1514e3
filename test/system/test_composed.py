"""The fault monitor composed in ``wavelet_stack`` decides as it does in its own process.

``amb-run`` twice on a mass loss at the first critical speed (PID only), once with a process per
node and once ``--composed`` (filterbank, monitor and controller in one process, the streams
handed over in process): the fault events in the two bags carry the same type, plane and sample
indices (onset, first crossing, decision), and every node reported the plant's last sample
(amb-run's drain). A third run composes the filterbank and controller with the monitor apart
(``--apart fault_monitor``: it reads the stack's coefficients over DDS): the same events. The
recorder composed in the stack (taking the streams and what the stack publishes in process)
writes as many messages of each stream topic as the recorder in its own process, with a queue
of 16 messages per topic: a DDS reader in the stack of the stack's own commands got nothing
until the lock-step stream stopped, then its queue's worth (here the first 16 commands; of a
long run, the first 5000). The
controller and filterbank of the composed process are compared with amb-sim bit for bit in
``test_lockstep_determinism``.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from rosbags.rosbag2 import Reader
from scenarios import first_critical_mass_loss

from amb_tools.bag_types import typestore

pytestmark = [pytest.mark.ros, pytest.mark.slow]

SCENARIO = first_critical_mass_loss(8.0, 3.0, name="composed")  # calibrated by 1.7 s


def _events(bag: Path) -> list[tuple]:
    store = typestore()
    out = []
    with Reader(bag) as reader:
        for conn, _t, raw in reader.messages():
            if conn.topic == "/amb/fault/events":
                e = store.deserialize_cdr(raw, conn.msgtype)
                out.append(
                    (e.fault_type, e.plane, e.onset_sample_index, e.detection_sample_index,
                     e.header.stamp.sec, e.header.stamp.nanosec)
                )  # fmt: skip
    return out


def _counts(bag: Path) -> dict[str, int]:
    with Reader(bag) as reader:
        return {c.topic: c.msgcount for c in reader.connections if c.topic != "/diagnostics"}


def _run(scenario: Path, out: Path, *extra: str) -> str:
    run = subprocess.run(
        [sys.executable, "-m", "amb_apps.run_cli", "--scenario", str(scenario),
         "--out", str(out), "--controller", "none", *extra],
        capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    logs = "\n".join(f"--- {p.name}\n{p.read_text()[-3000:]}" for p in (out / "logs").glob("*"))
    assert run.returncode == 0, run.stdout + run.stderr + logs
    assert "drained" in run.stdout, run.stdout
    return run.stdout


def test_composed_fault_monitor_gives_the_same_events(tmp_path, ros_domain_id) -> None:
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(SCENARIO))
    _run(scenario, tmp_path / "processes")
    depth = ("--set", "recorder.queue_depth:=16")
    stdout = _run(scenario, tmp_path / "composed", "--composed", *depth)
    last = int(re.search(r"processed the plant's last sample (\d+)", stdout).group(1))
    assert (tmp_path / "composed" / "logs" / "wavelet_stack.log").is_file()
    _run(scenario, tmp_path / "apart", "--composed", "--apart", "fault_monitor")
    assert {p.name for p in (tmp_path / "apart" / "logs").glob("*.log")} >= {
        "wavelet_stack.log", "fault_monitor.log"
    }  # fmt: skip
    separate = _events(tmp_path / "processes" / "bag")
    composed = _events(tmp_path / "composed" / "bag")
    assert separate, "the monitor found no fault in the mass loss"
    assert composed == separate
    assert _events(tmp_path / "apart" / "bag") == separate  # the stack's coefficients over DDS
    recorded = _counts(tmp_path / "processes" / "bag")
    assert recorded["/amb/measurement"] == last + 1  # every sample the plant produced
    assert _counts(tmp_path / "composed" / "bag") == recorded  # the recorder in the stack


def test_apart_needs_composed(tmp_path) -> None:
    run = subprocess.run(
        [sys.executable, "-m", "amb_apps.run_cli", "--scenario", "mass_loss_first_critical.yaml",
         "--out", str(tmp_path / "run"), "--apart", "fault_monitor"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert run.returncode == 2 and "--apart needs --composed" in run.stderr, run.stderr
