"""The node processes of an ``amb-run`` started by a test, found by its output folder."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import yaml


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


def start_run(tmp_path: Path, scenario: dict, *options: str) -> tuple[subprocess.Popen, Path]:
    """``amb-run`` on ``scenario`` (written to YAML) without a controller or fault monitor.

    Returns the process (stdout and stderr piped, text) and its output folder.
    """
    out = tmp_path / "run"
    path = tmp_path / f"{scenario['name']}.yaml"
    path.write_text(yaml.safe_dump(scenario))
    run = subprocess.Popen(
        [sys.executable, "-u", "-m", "amb_apps.run_cli", "--scenario", str(path),
         "--out", str(out), "--controller", "none", "--without", "fault_monitor", *options],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    return run, out


def read_until_plant_moves(run: subprocess.Popen) -> list[str]:
    """Read ``run``'s progress lines until the plant's simulated time has moved; return them."""
    progress = []
    for line in run.stdout:
        progress.append(line)
        if "t_sim =" in line and float(line.split("t_sim =")[1].split()[0]) > 0:
            break
    return progress


def left_after(out: Path, seconds: float) -> list[int]:
    """The run's node processes still there ``seconds`` from now (checked every 0.1 s)."""
    deadline = time.monotonic() + seconds
    while pids_of_run(out) and time.monotonic() < deadline:
        time.sleep(0.1)
    return pids_of_run(out)


def log_tails(out: Path, chars: int) -> str:
    """The last ``chars`` characters of every node log of the run."""
    return "\n".join(f"--- {p.name}\n{p.read_text()[-chars:]}" for p in (out / "logs").glob("*"))
