"""The node processes of an ``amb-run`` started by a test, found by its output folder."""

from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path


def pids_of_run(out: Path) -> list[int]:
    """The node processes of the run writing to ``out`` (their command line names its params)."""
    found = subprocess.run(["pgrep", "-f", str(out / "run_params.yaml")], capture_output=True)
    return [int(p) for p in found.stdout.split()]


def node_pid(out: Path, node: str) -> list[int]:
    """The processes of the run writing to ``out`` whose command line names ``node``."""
    pids = []
    for pid in pids_of_run(out):
        try:
            if node.encode() in Path(f"/proc/{pid}/cmdline").read_bytes():
                pids.append(pid)
        except OSError:
            pass
    return pids


def kill_run(out: Path) -> None:
    """Kill every node process of the run (continued first): none may outlive the test."""
    for pid in pids_of_run(out):
        for sig in (signal.SIGCONT, signal.SIGKILL):
            try:
                os.kill(pid, sig)
            except ProcessLookupError:
                pass
