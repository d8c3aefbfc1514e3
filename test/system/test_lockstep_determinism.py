"""The nodes over DDS (amb-run) and the in-process runner (amb-sim) give the same run.

Same scenario, same controller and model: the bag of the processes exchanging real messages
(each node its own process, or the filterbank and controller composed in ``wavelet_stack``,
handing the streams over in process) and the bag of the in-process lock-step loop carry
identical measurements, wavelet coefficients and commands (compared field by field after
deserialisation: the raw CDR may differ in trailing alignment padding between rclpy's serialiser
and Fast DDS).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from msg_fill import diff, to_plain
from rosbags.rosbag2 import Reader
from scenarios import first_critical_mass_loss

from amb_tools.bag_types import typestore

pytestmark = [pytest.mark.ros, pytest.mark.slow]

SCENARIO = first_critical_mass_loss(2.0, 0.8, name="determinism")
COMPARED = ("/amb/measurement", "/amb/wavelet/coefficients", "/amb/control/command")


def _messages(bag: Path) -> dict[str, list]:
    store = typestore()
    out: dict[str, list] = {}
    with Reader(bag) as reader:
        for conn, _t, raw in reader.messages():
            if conn.topic in COMPARED:
                out.setdefault(conn.topic, []).append(store.deserialize_cdr(raw, conn.msgtype))
    return out


def _cli(args: list[str]) -> subprocess.CompletedProcess:
    return subprocess.run(args, capture_output=True, text=True, timeout=600)


@pytest.mark.parametrize("composed", [False, True], ids=["processes", "composed"])
def test_amb_run_and_amb_sim_bags_are_identical(tmp_path, ros_domain_id, composed) -> None:
    """Separate processes, and the filterbank and controller composed in ``wavelet_stack``."""
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(SCENARIO))
    sim = _cli(
        [
            sys.executable, "-m", "amb_apps.sim_cli", "--scenario", str(scenario),
            "--controller", "transient", "--model", "fe", "--out", str(tmp_path / "sim"),
        ]
    )  # fmt: skip
    assert sim.returncode == 0, sim.stderr
    model = tmp_path / "sim" / "model.npz"
    assert model.is_file()
    run = _cli(
        [
            sys.executable, "-m", "amb_apps.run_cli", "--scenario", str(scenario),
            "--out", str(tmp_path / "run"), "--controller", "transient",
            "--without", "fault_monitor",
            "--set", f"wavelet_controller.model_file:={model}",
            "--set", "wavelet_controller.start_mode:=active",
            *(["--composed"] if composed else []),
        ]
    )  # fmt: skip
    assert run.returncode == 0, run.stdout + run.stderr
    logs = sorted(p.name for p in (tmp_path / "run" / "logs").iterdir())
    assert ("wavelet_stack.log" in logs) == composed, logs
    plant_log = (tmp_path / "run" / "logs" / "plant_sim.log").read_text()
    # every measurement reader counted (composed: the stack's one) before the plant starts
    assert "starting anyway" not in plant_log, plant_log
    a = _messages(tmp_path / "sim" / "bag")
    b = _messages(tmp_path / "run" / "bag")
    n_periods = round(
        SCENARIO["duration"]
        * float(to_plain(a["/amb/measurement"][0])["rotor_speed"])
        / (2 * 3.141592653589793)
    )
    assert len(a["/amb/measurement"]) == n_periods * 32
    for topic in COMPARED:
        assert len(a[topic]) == len(b[topic]), topic
        for i, (x, y) in enumerate(zip(a[topic], b[topic], strict=True)):
            assert diff(to_plain(x), to_plain(y)) == [], f"{topic}[{i}]"
    # the controller acted: commands with a non-zero force after the delay
    forces = [abs(v) for c in b["/amb/control/command"] for v in c.force]
    assert max(forces) > 1.0
