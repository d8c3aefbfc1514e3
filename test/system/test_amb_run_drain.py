"""amb-run stops the fault monitor only once it has processed the plant's last sample.

A fault monitor that lags the plant (off the lock-step chain, niced or starved on a loaded
machine) still has the end of the run in its subscription queues when the plant exits. Here the
lag is made deterministic: from the plant's start until a second after the plant has exited,
the monitor's process runs only 5 ms in every 250 ms (SIGSTOP / SIGCONT), so that it is still
far from the mass loss (its calibration alone takes 16 revolutions) when amb-run decides to stop
it. The run must still record the monitor's mass-loss event and a last monitor report that
reached the plant's last sample, and amb-run must say so.

The monitor is starved rather than stopped for good: a stopped process cannot acknowledge, and
the plant, which waits at most 10 s for its acknowledgements before it exits, would take the
unacknowledged measurements with it.
"""

from __future__ import annotations

import math
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from rosbags.rosbag2 import Reader
from scenarios import first_critical_mass_loss
from throttle import Throttle

from amb_tools.bag_types import typestore

pytestmark = [pytest.mark.ros, pytest.mark.slow]

#: Mass loss at 3.0 s: 16 revolutions of calibration and more before it (about 9.7 rev/s at
#: the model's first critical speed), and the run ends 2 s (about 19 revolutions) after it.
SCENARIO = first_critical_mass_loss(5.0, 3.0, name="drain")
MASS_LOSS = 1  # amb_msgs/FaultEvent.MASS_LOSS


def _children(pid: int) -> dict[str, int]:
    """Node name -> process id of the children of ``pid`` (from /proc)."""
    out = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            argv = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        ppid = int(stat.rsplit(")", 1)[1].split()[1])
        if ppid != pid:
            continue
        for arg in argv:
            name = Path(arg.decode()).name
            for node in ("fault_monitor", "plant_sim"):
                if name in (node, f"amb_{node}.node"):
                    out[node] = int(entry.name)
    return out


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (an exited child stays a zombie until it is reaped)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _bag(bag: Path) -> tuple[list, list, int]:
    """Fault events, the fault monitor's /diagnostics values, measurement indices of a bag."""
    store = typestore()
    events, reports, last = [], [], -1
    with Reader(bag) as reader:
        for conn, _t, raw in reader.messages():
            if conn.topic == "/amb/fault/events":
                events.append(store.deserialize_cdr(raw, conn.msgtype))
            elif conn.topic == "/diagnostics":
                msg = store.deserialize_cdr(raw, conn.msgtype)
                for s in msg.status:
                    if s.name == "fault_monitor":
                        reports.append({kv.key: kv.value for kv in s.values})
            elif conn.topic == "/amb/measurement":
                msg = store.deserialize_cdr(raw, conn.msgtype)
                last = max(last, int(msg.sample_index))
    return events, reports, last


def test_a_lagging_fault_monitor_is_drained_before_it_is_stopped(tmp_path, ros_domain_id) -> None:
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(SCENARIO))
    run = subprocess.Popen(
        [
            sys.executable, "-m", "amb_apps.run_cli", "--scenario", str(scenario),
            "--out", str(tmp_path / "run"), "--controller", "none",
        ],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    throttle = None
    try:
        # amb-run starts the plant last, once every subscription is up: starve the monitor then
        deadline = time.monotonic() + 300.0
        nodes = _children(run.pid)
        while "plant_sim" not in nodes and time.monotonic() < deadline:
            time.sleep(0.05)
            nodes = _children(run.pid)
        assert "plant_sim" in nodes, "amb-run did not start the plant"
        throttle = Throttle(nodes["fault_monitor"])
        throttle.start()
        while _alive(nodes["plant_sim"]) and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(1.0)  # amb-run has decided what to do with the monitor by now
    finally:
        if throttle is not None:
            throttle.release()
        output, _ = run.communicate(timeout=600)
    assert run.returncode == 0, output
    events, reports, last = _bag(tmp_path / "run" / "bag")
    fs = float(SCENARIO["samples_per_rev"]) * _speed(tmp_path / "run" / "bag") / (2 * math.pi)
    onset = SCENARIO["events"][1]["time"] * fs
    mass_loss = [e for e in events if e.fault_type == MASS_LOSS]
    assert mass_loss, f"no mass-loss event in the bag: {[e.description for e in events]}"
    assert abs(mass_loss[0].onset_sample_index - onset) <= SCENARIO["samples_per_rev"]
    # the monitor's last report in the bag: it had processed the run's last sample
    assert int(reports[-1]["last_sample"]) == last
    assert int(reports[-1]["last_coefficient_sample"]) == last  # odd: whole periods of 32
    assert f"every node processed the plant's last sample {last}" in output


def _speed(bag: Path) -> float:
    """rad/s, the rotor speed of the first measurement of a bag."""
    store = typestore()
    with Reader(bag) as reader:
        for conn, _t, raw in reader.messages():
            if conn.topic == "/amb/measurement":
                return float(store.deserialize_cdr(raw, conn.msgtype).rotor_speed)
    raise AssertionError("no measurement in the bag")
