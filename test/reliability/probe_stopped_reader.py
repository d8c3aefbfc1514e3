"""Probe, not a test of the suite: how often a stopped recorder blocks the lock-step writers.

Run by hand (its name keeps it out of the suite's collection)::

    python -m pytest -q -s test/reliability/probe_stopped_reader.py

The plant runs in lock-step (600 s of rotor time at 16 samples/rev) with the filterbank, the
controller and a recorder. The recorder is stopped (SIGSTOP) for 0.25 s, let go for 0.4 s, and
so on until the plant ends (``PROBE_CYCLES`` at most, 150). A stop in which the plant advanced
fewer than 20 samples is a blocked one: in 0.25 s its writers' histories (5000 messages) cannot
fill, so the plant is held inside a ``write`` (``amb_tools.lossless``, module notes). With
``gdb`` on the path, each blocked stop leaves every process's threads' backtraces and the
plant's mutex (its ``__owner`` is a thread id) in ``PROBE_DIR`` (default: the test's tmp dir).
The summary line is printed and appended to ``PROBE_DIR/summary.log``. ``PROBE_TRANSPORT=udp``
runs the recorder off shared memory (``AMB_TRANSPORT``, ``amb_tools.transport_profile``).
``docs/history.md``, "A stopped reader that blocks its writers", has the runs.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest
import yaml
from scenarios import steady_unbalance

pytestmark = [pytest.mark.ros, pytest.mark.slow]

SPR = 16
RUN = {
    **steady_unbalance("stopped_reader", 3.0, SPR, measurement_noise=2.0e-7),
    "name": "stopped_reader",
    "duration": 600.0,
}
TOTAL = round(RUN["duration"] * RUN["speed"]["hz"]) * SPR  # samples of the run
STOP_S, GO_S = 0.25, 0.4  # s the recorder is stopped, then let go, per cycle
BLOCKED_BELOW = 20  # samples the plant advanced in a stop: fewer is a blocked stop


def _backtraces(pid: int, mutex: bool) -> str:
    """Every thread's backtrace of ``pid`` (and, for the plant, its waited-on mutex)."""
    cmd = ["gdb", "-p", str(pid), "-batch", "-ex", "thread apply all bt 30"]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=120).stdout
    found = re.search(r"__pthread_mutex_clocklock_common \(mutex=(0x[0-9a-f]+)", out)
    if mutex and found:
        cmd = ["gdb", "-p", str(pid), "-batch", "-ex", f"p *(pthread_mutex_t*){found[1]}"]
        out += "==== mutex\n" + subprocess.run(cmd, capture_output=True, text=True).stdout
    return out


def test_probe_stopped_recorder(ros, node_process, tmp_path) -> None:
    from amb_msgs.msg import Measurement
    from reliability_helpers import Diagnostics

    from amb_tools.transport_profile import TRANSPORT_VARIABLE

    out_dir = Path(os.environ.get("PROBE_DIR", tmp_path))
    out_dir.mkdir(parents=True, exist_ok=True)
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(RUN))
    transport = os.environ.get("PROBE_TRANSPORT", "shm")
    recorder = node_process(
        "recorder",
        params={"output": str(tmp_path / "bag"), "topics": ["/amb/*"]},
        env={TRANSPORT_VARIABLE: transport},
    )
    filterbank = node_process("wavelet_filterbank", params={"samples_per_rev": SPR})
    controller = node_process(
        "wavelet_controller", params={"samples_per_rev": SPR, "controller": "none"}
    )
    node = ros.node("amb_probe_observer")
    tap = ros.tap(node, Measurement, "/amb/measurement", SPR, lambda raw: None, renew_after=300.0)
    writers = Diagnostics(node)
    assert ros.spin_until(
        lambda: (
            writers.matched("wavelet_filterbank", "/amb/wavelet/coefficients") >= 2
            and writers.matched("wavelet_controller", "/amb/control/command") >= 1
        ),
        60.0,
    ), (recorder.log(), filterbank.log(), controller.log())
    plant = node_process(
        "plant_sim",
        params={"scenario_file": str(scenario), "samples_per_rev": SPR,
                "wait_for_subscribers": 4, "command_timeout": 30.0},
    )  # fmt: skip
    assert ros.spin_until(lambda: tap.received >= 100, 60.0), plant.log()
    procs = (plant, filterbank, controller, recorder)
    gdb = shutil.which("gdb") is not None
    cycles = blocked = 0
    while plant.returncode is None and cycles < int(os.environ.get("PROBE_CYCLES", "150")):
        cycles += 1
        recorder.proc.send_signal(signal.SIGSTOP)
        before = tap.received
        ros.spin_for(STOP_S)
        # at the end the plant waits for every reader's acknowledgements: not a blocked stop
        if (
            tap.received - before < BLOCKED_BELOW
            and plant.returncode is None
            and not (tap.received >= TOTAL)
        ):
            blocked += 1
            if gdb:
                dump = "".join(
                    f"==== {p.name}\n{_backtraces(p.proc.pid, p is plant)}" for p in procs
                )
                (out_dir / f"blocked_{int(time.time())}_{cycles}.txt").write_text(dump)
        recorder.proc.send_signal(signal.SIGCONT)
        ros.spin_for(GO_S)
    log = plant.log()
    ros.spin_for(2.0)  # the recorder's last messages (the plant waited for every reader's acks)
    recorder.stop()
    written = re.search(r"messages written: (.*)", recorder.log())
    line = (
        f"recorder on {transport}: stops {cycles}, blocked {blocked}; plant: 'publication blocked' "
        f"{log.count('publication blocked')}, 'publication waiting' "
        f"{log.count('publication waiting')}; samples seen {tap.received}; readers moved "
        f"{[p.log().count('moved to a new participant') for p in procs]}; bag: "
        f"{written.group(1) if written else 'no summary'}"
    )
    print(line)
    with open(out_dir / "summary.log", "a") as fh:
        fh.write(line + "\n")
    assert cycles > 0
