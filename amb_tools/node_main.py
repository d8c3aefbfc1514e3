"""One ``main()`` for every node executable: init, spin, clean stop on SIGINT and SIGTERM.

rclpy's own signal handling covers SIGINT but a node may miss SIGTERM (``ros2 launch`` sends
SIGINT first, a process manager SIGTERM). :func:`run_node` installs handlers for both that only
set a flag, spins with a timeout so the flag is seen within ``spin_timeout`` seconds, then calls
the node's ``on_shutdown()`` (if it has one) before destroying it, so that files are closed.
A node that has finished its work (a simulator at the end of its scenario) sets ``done = True``
and the process exits with status 0.
A node whose constructor raises :class:`ConfigurationError` (invalid parameter or file) makes the
process exit with status 2 and the reason on stderr.

Once running, a node never dies of one bad callback: an exception escaping a callback (a bug, or
an input no check foresaw) is logged with its traceback (throttled), counted in the node's
``callback_errors`` attribute (the nodes report it on ``/diagnostics``) and spinning goes on.
Every input the nodes know to be invalid is rejected before it gets that far; this is the last
line, so that a peer's garbage never takes the rotor's control loop down.

Profiling (opt-in, for ``bench/``): with ``AMB_CPU_LOG=DIR`` in the environment the node writes,
at shutdown, ``DIR/<node name>.cpu.json``: the user and system CPU seconds of the process spent
while spinning (``os.times()``), the wall seconds spun, and a timeline of (monotonic s, CPU s)
sampled every 0.1 s by a daemon thread, so that the CPU a node spends per sample can be measured
over any window of a run; a node with a ``run_window`` attribute (monotonic s of its first and
last sample: ``plant_sim``) has it written too, and ``bench/pipeline_profile.py`` takes that
window. ``AMB_PROFILE=DIR`` does the same and also runs the spin loop under :mod:`cProfile`,
written to ``DIR/<node name>.prof`` (pstats; the profiler itself inflates the CPU times, and
with the ``EventsExecutor``, whose callbacks enter Python from C++, waiting time is charged to
whatever Python frame was current: read the callbacks' own functions). Without either variable
nothing changes.
"""

from __future__ import annotations

import cProfile
import gc
import json
import os
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import Field
from pathlib import Path
from types import FrameType

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from amb_tools.transport_profile import TransportError, transport_of, use_project_profile

EXIT_CONFIGURATION_ERROR = 2
#: Garbage collections longer than this (s) are listed in the CPU log (``AMB_CPU_LOG``).
GC_REPORTED_S = 0.002


class ConfigurationError(ValueError):
    """A node cannot start: a parameter or a file it names is invalid (the message says which)."""


def descriptor(
    description: str,
    read_only: bool = True,
    ints: tuple[int, int] | None = None,
    floats: tuple[float, float] | None = None,
) -> ParameterDescriptor:
    """A ``ParameterDescriptor`` with its description and, where given, its range.

    Parameters
    ----------
    description : str
        What the parameter is, with its unit.
    read_only : bool
        Structural parameters (wavelet, samples_per_rev, ...) are read-only.
    ints, floats : tuple, optional
        Inclusive ``(low, high)`` integer or floating-point range.
    """
    ranges = {}
    if ints is not None:
        ranges["integer_range"] = [IntegerRange(from_value=ints[0], to_value=ints[1])]
    if floats is not None:
        ranges["floating_point_range"] = [
            FloatingPointRange(from_value=floats[0], to_value=floats[1])
        ]
    return ParameterDescriptor(description=description, read_only=read_only, **ranges)


def field_descriptor(f: Field, ros_form: str = "") -> ParameterDescriptor:
    """The ROS descriptor of a :func:`~amb_common.config_fields.param` dataclass field.

    Its description (with ``ros_form``, how the ROS parameter carries a value it cannot hold,
    e.g. inf or an empty list, and the allowed values), read-only unless settable at run time,
    the range rclpy enforces (if any) and the allowed values also as ``additional_constraints``
    (``ros2 param describe`` shows both).
    """
    meta = f.metadata
    text = meta["description"]
    if ros_form:
        text += f" ({ros_form})"
    if meta["allowed"]:
        text += f"; allowed: {meta['allowed']}"
    out = descriptor(text, read_only=not meta["runtime"], ints=meta["ints"], floats=meta["floats"])
    if meta["allowed"]:
        out.additional_constraints = meta["allowed"]
    return out


def make_executor(choice: str | None = None):
    """The executor every node spins (``AMB_EXECUTOR``: ``events``, the default, or ``single``).

    rclpy's ``EventsExecutor`` (experimental in Jazzy) costs less Python per message than the
    ``SingleThreadedExecutor``: the lock-step loop runs faster and the realtime command latency
    is lower (``bench/pipeline.py`` with ``AMB_EXECUTOR=events`` and ``single``:
    docs/results.md#executor; the first measurement: ``docs/history.md``). Nodes spin
    it with a timeout only (``spin_once(timeout_sec=...)``): without one it was seen to run no
    callbacks. ``AMB_EXECUTOR=single`` returns to the standard executor; ``choice`` overrides
    the environment for one node (the recorder keeps ``single``, see its ``main``).

    Returns
    -------
    rclpy.executors.Executor
    """
    choice = choice or os.environ.get("AMB_EXECUTOR", "events")
    if choice == "events":
        return EventsExecutor()
    if choice != "single":
        raise ConfigurationError(f"AMB_EXECUTOR = {choice!r}: allowed 'single' or 'events'")
    return SingleThreadedExecutor()


def run_node(
    factory: Callable[[], Node],
    args: Sequence[str] | None = None,
    spin_timeout: float = 0.1,
    executor: str | None = None,
) -> int:
    """Create a node with ``factory`` and spin it until SIGINT, SIGTERM or shutdown.

    Parameters
    ----------
    factory : callable
        Builds the node (called after ``rclpy.init``).
    args : sequence of str, optional
        Command-line arguments (``--ros-args ...``); ``sys.argv`` if omitted.
    spin_timeout : float
        s, longest wait in one spin before the stop flag is checked.
    executor : str, optional
        ``"events"`` or ``"single"``; default ``AMB_EXECUTOR`` (see :func:`make_executor`).

    Returns
    -------
    int
        Process exit status: 0 on a clean stop, 2 on a configuration error.
    """
    return run_nodes([factory], args, spin_timeout, executor)


def run_nodes(
    factories: Sequence[Callable[[], Node]],
    args: Sequence[str] | None = None,
    spin_timeout: float = 0.1,
    executor: str | None = None,
    process_name: str | None = None,
) -> int:
    """Create nodes with ``factories`` (in order) and spin them in one executor.

    As :func:`run_node`, for several nodes composed in one process (``wavelet_stack``): a
    configuration error in any stops the process with status 2; the process ends when one node
    sets ``done``; a callback's exception is counted in the ``callback_errors`` of the node
    whose method raised it. Profiles (``AMB_CPU_LOG``, ``AMB_PROFILE``) are written under
    ``process_name`` (default: the first node's name).
    """
    stop = False

    def _request_stop(signum: int, frame: FrameType | None) -> None:
        nonlocal stop
        stop = True

    try:
        use_project_profile()  # before the first participant (amb_tools.transport_profile)
    except TransportError as exc:
        print(f"[ERROR] configuration: {exc}", file=sys.stderr, flush=True)
        return EXIT_CONFIGURATION_ERROR
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    previous = {s: signal.signal(s, _request_stop) for s in (signal.SIGINT, signal.SIGTERM)}
    nodes: list[Node] = []
    profiler = None
    try:
        try:
            for factory in factories:
                nodes.append(factory())
        except (ConfigurationError, ParameterException) as exc:
            # ParameterException: rclpy's own refusal of a -p / params-file value against its
            # descriptor (range, type); its message names the value, the reason and the name.
            print(f"[ERROR] configuration: {exc}", file=sys.stderr, flush=True)
            return EXIT_CONFIGURATION_ERROR
        policy = os.sched_getscheduler(0)
        if policy != os.SCHED_OTHER:  # started real-time (amb-run --rt-priority, chrt): say so
            label = {os.SCHED_FIFO: "SCHED_FIFO", os.SCHED_RR: "SCHED_RR"}.get(policy, policy)
            nodes[0].get_logger().info(
                f"scheduling: {label}, priority {os.sched_getparam(0).sched_priority}"
            )
        if transport_of(os.environ) == "udp":
            nodes[0].get_logger().info(
                "transport: UDPv4 only, no shared memory (AMB_TRANSPORT=udp; "
                "amb_tools/transport_profile.py)"
            )
        spinner = make_executor(executor)
        for node in nodes:
            spinner.add_node(node)
            node.callback_errors = 0
        # What exists now (modules, models, discretisations) lives as long as the process. A
        # full collection scanning it paused wavelet_stack for 28-64 ms at 67 Hz x 32 (four
        # control periods: a run of late commands); frozen, the collector leaves it out.
        gc.collect()
        gc.freeze()
        profiler = _Profiler.from_environment()
        if profiler is not None:
            profiler.start()
        while not stop and rclpy.ok() and not any(getattr(n, "done", False) for n in nodes):
            try:
                spinner.spin_once(timeout_sec=spin_timeout)
            except (KeyboardInterrupt, ExternalShutdownException):
                raise
            except Exception as exc:
                node = _raised_in(nodes, exc)
                node.callback_errors += 1
                node.get_logger().error(
                    f"callback error #{node.callback_errors} (node keeps running):\n"
                    + traceback.format_exc(),
                    throttle_duration_sec=5.0,
                )
        return 0
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        if profiler is not None:
            windows = [w for n in nodes if (w := getattr(n, "run_window", None)) is not None]
            profiler.dump(process_name or nodes[0].get_name(), windows[0] if windows else None)
        for node in reversed(nodes):
            on_shutdown = getattr(node, "on_shutdown", None)
            if on_shutdown is not None:
                on_shutdown()
            node.destroy_node()
        rclpy.try_shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _raised_in(nodes: Sequence[Node], exc: BaseException) -> Node:
    """The node whose method is deepest in ``exc``'s traceback (the first node if none is)."""
    found = nodes[0]
    for frame, _ in traceback.walk_tb(exc.__traceback__):
        owner = frame.f_locals.get("self")
        if any(owner is n for n in nodes):
            found = owner
    return found


def _run_queue_wait() -> tuple[float, int]:
    """The main thread's run-queue wait so far (s) and its times on a CPU (``schedstat``).

    (0.0, 0) where the kernel does not say (no ``/proc/self/schedstat``).
    """
    try:
        with open("/proc/self/schedstat") as f:
            fields = f.read().split()
        return int(fields[1]) * 1e-9, int(fields[2])
    except (OSError, IndexError, ValueError):
        return 0.0, 0


class _Profiler:
    """CPU times of the spin loop, optionally under cProfile (``AMB_CPU_LOG``, ``AMB_PROFILE``).

    Besides the CPU timeline (every 0.1 s), what can hold the loop up without CPU of its own:
    the main thread's run-queue wait (the kernel's ``schedstat``: another process had the
    core) on the same instants, and every garbage collection longer than
    :data:`GC_REPORTED_S` (the collector holds the GIL), so that a stall found in a run can be
    put on one of them, or on neither.
    """

    def __init__(self, folder: Path, cprofile: bool) -> None:
        self.folder = folder
        self.profile = cProfile.Profile() if cprofile else None

    @classmethod
    def from_environment(cls) -> _Profiler | None:
        if folder := os.environ.get("AMB_PROFILE"):
            return cls(Path(folder), cprofile=True)
        if folder := os.environ.get("AMB_CPU_LOG"):
            return cls(Path(folder), cprofile=False)
        return None

    def start(self) -> None:
        self._cpu0 = os.times()
        self._wall0 = time.monotonic()
        self._timeline: list[tuple[float, float]] = []
        self._run_queue: list[tuple[float, float, int]] = []
        self._gc_started = 0.0
        self._gc_count = 0
        self._gc_long: list[tuple[float, float, int]] = []  # (start, seconds, generation)
        gc.callbacks.append(self._on_gc)
        self._stop = threading.Event()
        threading.Thread(target=self._sample, daemon=True).start()
        if self.profile is not None:
            self.profile.enable()

    def _on_gc(self, phase: str, info: dict) -> None:
        now = time.monotonic()
        if phase == "start":
            self._gc_started = now
            return
        self._gc_count += 1
        if now - self._gc_started > GC_REPORTED_S:
            self._gc_long.append((self._gc_started, now - self._gc_started, info["generation"]))

    def _sample(self) -> None:
        while not self._stop.wait(0.1):
            cpu = os.times()
            now = time.monotonic()
            self._timeline.append((now, cpu.user + cpu.system))
            self._run_queue.append((now, *_run_queue_wait()))

    def dump(self, name: str, run_window: tuple[float, float] | None = None) -> None:
        if self.profile is not None:
            self.profile.disable()
        self._stop.set()
        gc.callbacks.remove(self._on_gc)
        cpu = os.times()
        self.folder.mkdir(parents=True, exist_ok=True)
        if self.profile is not None:
            self.profile.dump_stats(self.folder / f"{name}.prof")
        usage = {
            "user_s": cpu.user - self._cpu0.user,
            "system_s": cpu.system - self._cpu0.system,
            "wall_s": time.monotonic() - self._wall0,
            "end_monotonic_s": time.monotonic(),
            "timeline": self._timeline,
            # (monotonic s, the main thread's total run-queue wait s, its times on a CPU)
            "run_queue_wait": self._run_queue,
            "gc": {
                "collections": self._gc_count,
                "longer_than_s": GC_REPORTED_S,
                "long": self._gc_long,
            },
        }
        if run_window is not None:  # a node's own (first, last) sample, monotonic s
            usage["run_window"] = list(run_window)
        (self.folder / f"{name}.cpu.json").write_text(json.dumps(usage) + "\n")
