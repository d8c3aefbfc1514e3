"""amb-run aborts a run whose plant stopped making progress, and says where to look.

A plant whose loop broke (an exception in every command callback once left one spinning at
100 % CPU with its simulated time standing still) or that is stopped kept ``amb-run`` waiting
for its ``--timeout`` (an hour). With ``--stall-timeout`` it stops the run when the plant's
simulated time has not moved for that long, exits 1, prints the plant's last log lines, and
leaves no node behind. Here the plant is stopped (SIGSTOP) mid-run.
"""

from __future__ import annotations

import os
import signal

import pytest
from runs import kill_run, left_after, log_tails, node_pid, read_until_plant_moves, start_run
from scenarios import steady_unbalance

pytestmark = [pytest.mark.ros, pytest.mark.slow]

STALL_S = 3.0
#: Long enough that the plant is still running when the test stops it (an idle machine ran the
#: 30 s identification scenario through before amb-run's first progress line).
SCENARIO = steady_unbalance("stall", 600.0)


def test_a_stopped_plant_aborts_the_run_with_its_log(tmp_path, ros_domain_id) -> None:
    run, out = start_run(tmp_path, SCENARIO, "--stall-timeout", str(STALL_S))
    try:
        progress = read_until_plant_moves(run)
        plant = node_pid(out, "plant_sim")
        assert len(plant) == 1, (plant, progress, run.poll())
        os.kill(plant[0], signal.SIGSTOP)
        stdout, stderr = run.communicate(timeout=120)
    finally:
        if run.poll() is None:
            run.kill()
            run.wait()
        if run.returncode != 1:
            kill_run(out)  # amb-run did not stop its nodes: they would talk to later tests
    logs = log_tails(out, 2000)
    assert run.returncode == 1, "".join(progress) + stdout + stderr + logs
    assert "--stall-timeout" in stderr and "plant_sim.log" in stderr, stderr
    assert "samples/rev" in stderr  # the plant's own log lines are shown
    left = left_after(out, 10.0)
    kill_run(out)
    assert not left, "node processes left behind"
