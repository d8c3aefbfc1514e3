"""The processes of an ``amb-run``: how each is started, scheduled and connected.

:class:`NodeRun` starts one node executable (or ``wavelet_stack``) with its niceness, its
real-time priority and its DDS transport, and stops it; :func:`per_process`,
:func:`rt_priorities` and :func:`transports` read the options that choose them per process
(``--nice``, ``--rt-priority``, ``--udp`` / ``--shm``), each refused with its reason before
anything is started. Why each exists: :mod:`amb_apps.run_cli`'s notes, "Scheduling" and
"Transport".
"""

from __future__ import annotations

import importlib.util
import os
import signal
import subprocess
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from amb_apps.lifetime import die_with_parent
from amb_apps.system import NODE_MODULES, NODES, OFF_SHARED_MEMORY, STACK
from amb_tools.transport_profile import TRANSPORT_VARIABLE

__all__ = [
    "INSTALL_LIB",
    "NICENESS",
    "PROCESSES",
    "NodeRun",
    "available",
    "executable",
    "per_process",
    "rt_priorities",
    "transports",
]

INSTALL_LIB = Path(__file__).resolve().parent.parent / "install" / "amb_wavelet_control" / "lib"
#: Nice value added to the nodes that are not on the control loop's chain.
# fault_monitor is not niced by default: niced, it lags the lock-step chain and the end of the
# run waits for it to drain (what it did before runs drained: docs/history.md, "amb-run").
NICENESS = {"recorder": 10}
#: What ``--rt-priority``, ``--udp`` and ``--shm`` may name: a node's process, or the stack's.
PROCESSES = (*NODES, STACK)


@dataclass
class NodeRun:
    """One node process of the run."""

    name: str
    cmd: list[str]
    log_path: Path
    proc: subprocess.Popen | None = None
    extra: dict = field(default_factory=dict)
    nice: int = 0
    #: ``SCHED_FIFO`` priority of the process (1-99); 0: the ordinary policy.
    rt_priority: int = 0
    #: The nodes the process hosts (``wavelet_stack``: several; default: the one named).
    hosts: tuple[str, ...] = ()
    #: The process's DDS transport (``AMB_TRANSPORT``): ``shm`` (Fast DDS's) or ``udp``.
    transport: str = "shm"

    def __post_init__(self) -> None:
        self.hosts = self.hosts or (self.name,)

    def start(self, env: dict) -> None:
        """Start the process, output to its log file.

        ``nice`` is added to its niceness; ``rt_priority``, if given, puts it under
        ``SCHED_FIFO``; ``transport`` ``udp`` takes it off shared memory (module notes).
        """
        if self.transport != "shm":
            env = {**env, TRANSPORT_VARIABLE: self.transport}
        self._log = open(self.log_path, "w")
        nice, rt = self.nice, self.rt_priority

        def scheduling() -> None:  # in the child, before exec: every thread it makes inherits
            if nice:
                os.nice(nice)
            if rt:
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(rt))

        self.proc = subprocess.Popen(
            self.cmd,
            stdout=self._log,
            stderr=subprocess.STDOUT,
            env=env,
            preexec_fn=die_with_parent(then=scheduling if nice or rt else None),
        )

    def stop(self, timeout: float = 20.0) -> int:
        """SIGINT, wait, then SIGKILL; return the exit status (a stopped process is continued)."""
        if self.proc is None:  # never started (the run was stopped before its turn)
            return 0
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGCONT)  # else SIGINT waits while it is stopped
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
        self._log.close()
        return self.proc.returncode


def _installed(name: str) -> Path:
    """Where colcon installs node ``name``'s executable."""
    return INSTALL_LIB / "amb_wavelet_control" / name


def executable(name: str) -> list[str]:
    """Command that starts node ``name`` (the colcon-installed executable, else ``-m``)."""
    path = _installed(name)
    if path.exists():
        return [str(path)]
    return [sys.executable, "-m", NODE_MODULES[name]]


def per_process(
    option: str,
    items: list[str],
    names: Sequence[str],
    form: str,
    signed: bool = False,
    valid: Callable[[int], bool] = lambda value: True,
) -> dict[str, int]:
    """Parse the ``NAME=N`` items of a repeatable option (``--nice``, ``--rt-priority``).

    Raises
    ------
    SystemExit
        An item whose NAME is not in ``names``, whose N is not an integer (no sign unless
        ``signed``) or not ``valid``: ``amb-run: OPTION ITEM: expected FORM``.
    """
    out: dict[str, int] = {}
    for item in items:
        name, _, value = item.partition("=")
        digits = value[1:] if signed and value.startswith("-") else value
        if name not in names or not digits.isdigit() or not valid(int(value)):
            raise SystemExit(f"amb-run: {option} {item!r}: expected {form}")
        out[name] = int(value)
    return out


def rt_priorities(items: list[str]) -> dict[str, int]:
    """Parse ``--rt-priority PROCESS=P`` and check that this user may set it (module notes).

    Returns
    -------
    dict
        ``SCHED_FIFO`` priority by process name.

    Raises
    ------
    SystemExit
        A malformed item, an unknown process, P outside 1-99, or no right to the policy: the
        reason, before any process starts (a ``preexec_fn`` that failed would only say that
        one did).
    """
    form = f"PROCESS=P with P in 1-99 and PROCESS in {PROCESSES}"
    out = per_process("--rt-priority", items, PROCESSES, form, valid=lambda p: 1 <= p <= 99)
    if out:
        top = max(out.values())
        probe = subprocess.run(
            [sys.executable, "-c", f"import os; os.sched_setscheduler(0, os.SCHED_FIFO, "
             f"os.sched_param({top}))"],
            capture_output=True, text=True,
        )  # fmt: skip
        if probe.returncode != 0:
            reason = probe.stderr.strip().splitlines()[-1] if probe.stderr.strip() else "?"
            raise SystemExit(
                f"amb-run: --rt-priority: this user may not run a process under SCHED_FIFO at "
                f"priority {top} ({reason}); it needs root, CAP_SYS_NICE, or an rtprio limit "
                "of at least that priority (/etc/security/limits.conf)"
            )
    return out


def transports(udp: list[str], shm: list[str]) -> dict[str, str]:
    """The transport of each process named by ``--udp`` / ``--shm`` or ``OFF_SHARED_MEMORY``.

    Raises
    ------
    SystemExit
        A name that is not a process, or one named by both options.
    """
    for name in (*udp, *shm):
        if name not in PROCESSES:
            raise SystemExit(f"amb-run: --udp/--shm {name!r}: expected one of {PROCESSES}")
    if both := sorted(set(udp) & set(shm)):
        raise SystemExit(f"amb-run: {', '.join(both)} named by both --udp and --shm")
    chosen = {n: "udp" for n in (*OFF_SHARED_MEMORY, *udp)}
    return chosen | {n: "shm" for n in shm}


def available(name: str) -> bool:
    """Whether node ``name`` can be started (installed, or its module importable)."""
    if _installed(name).exists():
        return True
    module = executable(name)[-1]
    return module.startswith("amb_") and importlib.util.find_spec(module) is not None
