"""``amb-run --rt-priority PROCESS=P``: a process and its threads under SCHED_FIFO, or a refusal.

The policy is set in the child before it runs anything, so every thread it makes (a node's DDS
transport threads) inherits it; the kernel reports it per thread. A malformed item, an unknown
process or a priority outside 1-99 is refused with the reason before the run's folder is made
(as a bad ``--nice`` item is, by the same parser); so is a user without the right to the policy
(the check runs in a child, as the nodes would).
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from amb_apps.run_cli import build_parser, run
from amb_apps.run_processes import NodeRun, rt_priorities

PRIORITY = 7
#: The child prints its main thread's and a new thread's policy and priority.
PROBE = (
    "import os, threading\n"
    "def show():\n"
    "    print(os.sched_getscheduler(0), os.sched_getparam(0).sched_priority, flush=True)\n"
    "show()\n"
    "t = threading.Thread(target=show); t.start(); t.join()\n"
)


RT_REFUSAL = "expected PROCESS=P with P in 1-99"
NICE_REFUSAL = "expected NODE=N with NODE in"


@pytest.mark.parametrize(
    ("option", "item", "reason"),
    [
        *(("--rt-priority", i, RT_REFUSAL) for i in
          ("plant_sim=0", "plant_sim=100", "plant_sim=x", "plant=5", "wavelet_stack")),
        *(("--nice", i, NICE_REFUSAL) for i in ("fault_monitor=x", "fault_monitor=--5", "plant=3")),
    ],
)  # fmt: skip
def test_a_bad_item_is_refused_before_anything_is_made(
    tmp_path, option: str, item: str, reason: str
) -> None:
    out = tmp_path / "run"
    args = build_parser().parse_args(
        ["--scenario", "mass_loss_first_critical.yaml", "--out", str(out), option, item]
    )
    with pytest.raises(SystemExit) as refused:
        run(args)
    assert reason in str(refused.value)
    assert not out.exists()


def _may_use_fifo(priority: int) -> bool:
    """Whether this user may run a process under SCHED_FIFO, asked of the kernel directly."""
    code = f"import os; os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param({priority}))"
    return subprocess.run([sys.executable, "-c", code], capture_output=True).returncode == 0


def test_the_process_and_its_threads_run_under_sched_fifo_or_the_user_is_told_why(
    tmp_path,
) -> None:
    if not _may_use_fifo(PRIORITY):
        with pytest.raises(SystemExit) as refused:
            rt_priorities([f"plant_sim={PRIORITY}"])
        assert "may not run a process under SCHED_FIFO" in str(refused.value)
        return
    assert rt_priorities([f"plant_sim={PRIORITY}", "wavelet_stack=3"]) == {
        "plant_sim": PRIORITY,
        "wavelet_stack": 3,
    }
    log = tmp_path / "probe.log"
    child = NodeRun("plant_sim", [sys.executable, "-c", PROBE], log, rt_priority=PRIORITY)
    child.start(dict(os.environ))
    assert child.proc.wait(30) == 0, log.read_text()
    child.stop()
    lines = log.read_text().split("\n")
    expected = f"{os.SCHED_FIFO} {PRIORITY}"
    assert lines[:2] == [expected, expected], log.read_text()  # main thread, then a new one
