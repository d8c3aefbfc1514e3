"""
The subprocesses of ``tools/results.py``: :class:`Command`, its :class:`Output`, and running it.

A section of ``docs/results.md`` is made by running the project's own commands from the
repository root (``ROOT``); :func:`run_command` streams their output to stderr as progress and
raises :class:`results_parsers.ResultsError` on an exit status the command does not allow.
"""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from results_parsers import ResultsError

ROOT = Path(__file__).resolve().parents[1]


@dataclass
class Command:
    """One subprocess of a section: argv, extra environment, allowed exit statuses."""

    argv: list[str]
    env: dict[str, str] = field(default_factory=dict)
    ok: tuple[int, ...] = (0,)
    echo_stdout: bool = False  # stream stdout to stderr as progress (human-readable output)
    why: str = ""  # what an allowed non-zero status means

    def shell(self) -> str:
        """The command as one would type it (``python`` for this interpreter)."""
        env = " ".join(f"{k}={shlex.quote(v)}" for k, v in self.env.items())
        argv = ["python" if self.argv[0] == sys.executable else self.argv[0], *self.argv[1:]]
        return (env + " " if env else "") + shlex.join(argv)


@dataclass
class Output:
    """What a command printed, its status and how long it took."""

    command: Command
    stdout: str
    stderr: str
    returncode: int
    wall_s: float


def _pump(stream, sink: list[str], echo: bool) -> None:
    for line in stream:
        sink.append(line)
        if echo:
            print(f"[results]   | {line.rstrip()}", file=sys.stderr, flush=True)
    stream.close()


def run_command(section: str, cmd: Command, work: Path) -> Output:
    """Run ``cmd`` from the repository root; raise :class:`ResultsError` unless it succeeds."""
    exe = cmd.argv[0]
    if shutil.which(exe) is None and not Path(exe).is_file():
        raise ResultsError(
            f"{section}: `{exe}` is not on PATH: run `source tools/env.sh` first (or use "
            "`make results`, which does)"
        )
    env = {**os.environ, **cmd.env}
    print(f"[results] {section}: {cmd.shell()}", file=sys.stderr, flush=True)
    t0 = time.monotonic()
    proc = subprocess.Popen(
        cmd.argv,
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        errors="replace",
    )
    out: list[str] = []
    err: list[str] = []
    threads = [
        threading.Thread(target=_pump, args=(proc.stdout, out, cmd.echo_stdout)),
        threading.Thread(target=_pump, args=(proc.stderr, err, True)),
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    rc = proc.wait()
    wall = time.monotonic() - t0
    result = Output(cmd, "".join(out), "".join(err), rc, wall)
    print(f"[results] {section}: exit {rc} after {wall:.1f} s", file=sys.stderr, flush=True)
    if rc not in cmd.ok:
        tail = "\n".join((result.stdout + result.stderr).splitlines()[-20:])
        raise ResultsError(
            f"{section}: `{cmd.shell()}` exited with status {rc} (allowed: "
            f"{', '.join(map(str, cmd.ok))}); last lines of its output:\n{tail}"
        )
    return result
