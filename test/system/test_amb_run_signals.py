"""An amb-run that is terminated or killed leaves no node running, and its bag closed.

Before: SIGTERM ended ``amb-run`` by Python's default, without its cleanup, and SIGKILL
cannot be caught: in both cases the plant, filterbank, controller and recorder ran on through
their scenario on the run's ROS domain (measured: all five still running 8 s after either).
Now SIGTERM stops the run as Ctrl-C does (exit 128 + 15) and a killed ``amb-run``'s nodes get
SIGINT from the kernel (``PR_SET_PDEATHSIG``): either way every node stops, the recorder
closing its bag with every message it wrote.
"""

from __future__ import annotations

import os
import re
import signal

import pytest
from rosbags.rosbag2 import Reader
from runs import kill_run, left_after, log_tails, pids_of_run, read_until_plant_moves, start_run
from scenarios import steady_unbalance

pytestmark = [pytest.mark.ros, pytest.mark.slow]

#: Long enough that the plant is still running when the test signals amb-run.
SCENARIO = steady_unbalance("signalled", 600.0)
#: Wall s the nodes may take to stop (a node's SIGINT shutdown takes about a second here).
STOP_WITHIN = 30.0


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL], ids=["SIGTERM", "SIGKILL"])
def test_a_signalled_run_leaves_no_node_and_a_closed_bag(tmp_path, ros_domain_id, sig) -> None:
    run, out = start_run(tmp_path, SCENARIO)
    progress: list[str] = []
    left: list[int] = []
    try:
        progress = read_until_plant_moves(run)
        running = len(pids_of_run(out))
        os.kill(run.pid, sig)
        stdout, stderr = run.communicate(timeout=60)
        left = left_after(out, STOP_WITHIN)
    finally:
        if run.poll() is None:
            run.kill()
            run.wait()
        kill_run(out)  # whatever the outcome, nothing of this run talks to later tests
    context = "".join(progress) + stdout + stderr + log_tails(out, 1500)
    assert running == 4, context  # plant, filterbank, controller, recorder were up
    assert not left, f"node processes still running {STOP_WITHIN:g} s later\n{context}"
    if sig == signal.SIGTERM:
        assert run.returncode == 128 + signal.SIGTERM, context
        assert "SIGTERM: stopping the nodes" in stderr, context
    else:
        assert run.returncode == -signal.SIGKILL, context
    recorder_log = (out / "logs" / "recorder.log").read_text()
    closed = re.search(r"closed; messages written: (.*)", recorder_log)
    assert closed, context
    written = dict(re.findall(r"(/\S+): (\d+)", closed.group(1)))
    counts: dict[str, int] = {}
    with Reader(out / "bag") as reader:  # a bag closed with its metadata
        for conn, _t, _raw in reader.messages():
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
    assert counts["/amb/measurement"] > 0, counts
    assert {t: str(n) for t, n in counts.items()} == written, (counts, written)
