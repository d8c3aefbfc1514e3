"""Children tied to their parent; stop signals recorded, raised where checked (amb_apps.lifetime).

No ROS: plain processes. The child-side check: a grandchild started with
:func:`die_with_parent` by a parent that is then killed (SIGKILL, no cleanup) must get its
signal from the kernel; one started without it runs on (the control case: the test can fail).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from amb_apps.lifetime import RunStopped, StopSignals

#: A parent that starts a sleeping child (tied or not), prints the child's pid, then waits.
PARENT = """
import subprocess, sys, time
from amb_apps.lifetime import die_with_parent
tied = sys.argv[1] == "tied"
child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"],
                         preexec_fn=die_with_parent(signal_number) if tied else None)
print(child.pid, flush=True)
time.sleep(60)
""".replace("signal_number", str(int(signal.SIGTERM)))


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="prctl is Linux's")
@pytest.mark.parametrize("tied", [True, False], ids=["tied", "untied"])
def test_a_killed_parent_takes_a_tied_child_with_it(tied: bool) -> None:
    parent = subprocess.Popen(
        [sys.executable, "-c", PARENT, "tied" if tied else "free"], stdout=subprocess.PIPE
    )
    child = int(parent.stdout.readline())
    try:
        assert _alive(child)
        parent.kill()
        parent.wait()
        deadline = time.monotonic() + 5.0  # the kernel's signal comes at once
        while _alive(child) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert _alive(child) is not tied
    finally:
        if _alive(child):
            os.kill(child, signal.SIGKILL)


def test_sigterm_is_recorded_raised_once_where_checked_then_only_noticed() -> None:
    noticed: list[str] = []
    before = {s: signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGHUP)}
    stop = StopSignals(noticed.append)
    try:
        stop.check()  # nothing yet
        os.kill(os.getpid(), signal.SIGTERM)
        # the handler runs at the next bytecode and raises nothing there: an exception raised
        # inside a C++ call (rclpy's spin_once) came out of pybind11 as a RuntimeError
        deadline = time.monotonic() + 5.0
        while stop.signum is None and time.monotonic() < deadline:
            time.sleep(0.01)
        assert stop.signum == signal.SIGTERM
        with pytest.raises(RunStopped) as stopped:
            stop.check()
        assert stopped.value.signum == signal.SIGTERM
        os.kill(os.getpid(), signal.SIGHUP)  # the cleanup goes on
        time.sleep(0.05)
        stop.check()  # raised once only
        assert noticed == ["SIGHUP again: already stopping"]
    finally:
        stop.restore()
    assert {s: signal.getsignal(s) for s in before} == before
