"""Harness for tests that run real ROS 2 nodes over DDS (no mocks of rclpy).

- :func:`claim_domain_id` gives each pytest process its own ``ROS_DOMAIN_ID`` (held by a lock
  file in the temp folder), so parallel test runs on one machine never see each other; DDS
  discovery is kept on this machine (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``).
- :class:`RosTestContext` is one rclpy ``Context`` with its own executor, for in-process nodes.
- :class:`NodeProcess` starts a node executable as a separate process, as ``ros2 run`` would,
  with ``--ros-args --params-file``, and stops it with SIGINT or SIGTERM.
- :meth:`RosTestContext.tap` is a test's own reader of a sample-rate stream (:class:`StreamTap`):
  it takes every queued message at each wake and moves to a new participant if the transport
  stops feeding it, like the nodes' readers, so that an observer outside the loop keeps up.
- :func:`spin_until` spins an executor until a condition holds or a timeout passes;
  :meth:`RosTestContext.spin_until_progress` waits as long as a progress count keeps moving
  (samples processed), so that a slow, loaded machine is waited for and a stalled node is not.

Every node a test starts through the ``node_process`` fixture has its log attached to the
test's report when the test fails or times out (``test/conftest.py``).
"""

from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from amb_apps.lifetime import die_with_parent
from amb_apps.system import param_text

ROOT = Path(__file__).resolve().parents[2]
INSTALL_LIB = ROOT / "install" / "amb_wavelet_control" / "lib" / "amb_wavelet_control"
_domain_lock = None


def claim_domain_id(first: int = 40, last: int = 100) -> int:
    """Claim a ROS domain id no other test process on this machine holds; set it in the env.

    Returns
    -------
    int
        The domain id, also written to ``os.environ['ROS_DOMAIN_ID']``.

    Raises
    ------
    RuntimeError
        If every id in ``[first, last)`` is held.
    """
    global _domain_lock
    if _domain_lock is not None:
        return int(os.environ["ROS_DOMAIN_ID"])
    for domain in range(first, last):
        fh = open(Path(tempfile.gettempdir()) / f"amb-ros-domain-{domain}.lock", "w")
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.close()
            continue
        _domain_lock = fh
        os.environ["ROS_DOMAIN_ID"] = str(domain)
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        return domain
    raise RuntimeError(f"all ROS domain ids {first}..{last - 1} are held by other test runs")


class RosTestContext:
    """An isolated rclpy context with a single-threaded executor and its nodes."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.nodes: list = []
        self.taps: list[StreamTap] = []

    def tap(self, *args, **kwargs) -> StreamTap:
        """``StreamTap(*args, **kwargs)`` on one of this context's nodes, closed with it."""
        tap = StreamTap(*args, **kwargs)
        self.taps.append(tap)
        return tap

    def node(self, name: str, **kwargs: object):
        """Create a node in this context and add it to the executor."""
        import rclpy

        node = rclpy.create_node(name, context=self.context, **kwargs)
        self.executor.add_node(node)
        self.nodes.append(node)
        return node

    def spin_until(self, predicate: Callable[[], bool], timeout: float, step: float = 0.02) -> bool:
        """Spin until ``predicate()`` is true; return whether it became true in time."""
        return spin_until(self.executor, predicate, timeout, step)

    def spin_until_progress(
        self,
        predicate: Callable[[], bool],
        progress: Callable[[], object],
        stall: float = 30.0,
        limit: float = 900.0,
    ) -> bool:
        """
        Spin until ``predicate()`` holds, for as long as ``progress()`` keeps changing.

        Parameters
        ----------
        predicate : callable
            The condition waited for.
        progress : callable
            A measure of the work done (samples received, a node's ``last_sample``); any
            change of its value counts as progress.
        stall : float
            Give up after this many seconds without progress.
        limit : float
            Give up after this many seconds in all (a bound for a node that makes progress
            for ever without reaching the condition).

        Returns
        -------
        bool
            Whether the condition held before the wait gave up.
        """
        start = time.monotonic()
        seen, since = progress(), start
        while not predicate():
            now = time.monotonic()
            value = progress()
            if value != seen:
                seen, since = value, now
            elif now - since > stall or now - start > limit:
                return False
            self.executor.spin_once(timeout_sec=0.02)
        return True

    def stream_writers(self, node, samples_per_rev: int, proc: NodeProcess):
        """
        Measurement and coefficient writers on ``node``, matched with the node under test.

        Returns ``(measurement_publisher, coefficients_publisher)`` on ``/amb/measurement`` and
        ``/amb/wavelet/coefficients`` with the streams' QoS, once ``proc`` subscribes to both
        (30 s, else the assertion shows its log).
        """
        from amb_msgs.msg import Measurement, WaveletCoefficients

        from amb_tools.streams import stream_qos

        qos = stream_qos(samples_per_rev)
        pm = node.create_publisher(Measurement, "/amb/measurement", qos)
        pc = node.create_publisher(WaveletCoefficients, "/amb/wavelet/coefficients", qos)
        assert self.spin_until(
            lambda: pm.get_subscription_count() and pc.get_subscription_count(), 30.0
        ), proc.log()
        return pm, pc

    def spin_for(self, seconds: float) -> None:
        """Spin for a fixed time."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)

    def close(self) -> None:
        """Close the taps' own participants, destroy the nodes and shut the context down."""
        for tap in self.taps:
            tap.close()
        for node in self.nodes:
            self.executor.remove_node(node)
            node.destroy_node()
        self.executor.shutdown()
        self.context.try_shutdown()


class StreamTap:
    """A test's reader of a sample-rate stream that keeps every message it is sent.

    An observer outside a lock-step loop (the test process, beside the plant and the nodes on
    two cores) should keep up with the plant, or hold it once the writer's history is full of
    samples it has not acknowledged (lock-step writers keep every message, amb_tools.lossless).
    rclpy's executor hands over one message per wake, a wait set per message; this reader takes
    every message queued at a wake (:class:`amb_tools.backlog.BacklogReader` without a catch-up
    bound) as raw CDR, into a queue 65536 deep. A reader the transport stops feeding
    (``docs/history.md``, "A reader the transport stopped feeding") moves to a participant of
    its own after ``renew_after`` s of silence with the writer matched
    (:class:`amb_tools.reader_participant.DeafReaders`), as the nodes' readers do.

    Parameters
    ----------
    node : rclpy.node.Node
        The test's node; spun by its context's executor.
    msg_type : type
        Message class of the topic.
    topic : str
        Topic name.
    samples_per_period : int
        Samples per control period (the stream's QoS, :func:`amb_tools.streams.stream_qos`).
    on_message : callable, optional
        Called with each message's CDR bytes, oldest first; default: kept in :attr:`raw`.
    renew_after : float
        s of silence, with the writer matched, before the reader moves (longer than a plant's
        wait for a command, so that a plant on its watchdog does not count as silence).

    Attributes
    ----------
    raw : list of bytes
        The messages, when no ``on_message`` is given.
    received : int
        Messages received.
    """

    def __init__(
        self,
        node,
        msg_type: type,
        topic: str,
        samples_per_period: int,
        on_message: Callable[[bytes], None] | None = None,
        renew_after: float = 2.0,
    ) -> None:
        from amb_tools.backlog import BacklogReader
        from amb_tools.reader_participant import DeafReaders
        from amb_tools.streams import stream_qos

        self.raw: list[bytes] = []
        self.received = 0
        self._on_message = self.raw.append if on_message is None else on_message
        qos = stream_qos(samples_per_period)
        qos.depth = 1 << 16
        self.reader = BacklogReader(node, msg_type, topic, self._deliver, qos)
        self.deaf = DeafReaders(node, [self.reader], lambda: self.received, renew_after)

    @property
    def renewals(self) -> int:
        """Times the reader moved to a new participant."""
        return self.deaf.renewals

    def _deliver(self, raw: bytes) -> None:
        self.received += 1
        self._on_message(raw)

    def close(self) -> None:
        """Close the reader's own participant, if one was made."""
        self.deaf.close()


def spin_until(executor, predicate: Callable[[], bool], timeout: float, step: float = 0.02) -> bool:
    """Spin ``executor`` until ``predicate()`` holds or ``timeout`` (s) passes."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            return False
        executor.spin_once(timeout_sec=step)
    return True


class NodeProcess:
    """A node executable running as its own process.

    Parameters
    ----------
    executable : str
        Name of an installed node executable (``install/amb_wavelet_control/lib/...``), a
        Python module path prefixed with ``-m `` (e.g. ``-m amb_tools.recorder_node``), or the
        path of a Python script ending in ``.py``.
    log_dir : pathlib.Path
        Folder for the process's stdout/stderr log.
    params_file : pathlib.Path, optional
        Passed as ``--ros-args --params-file``.
    params : dict, optional
        Passed as ``-p name:=value``.
    extra_args : sequence of str
        More ``--ros-args`` arguments (remappings ``-r``).
    env : dict, optional
        Variables added to (or replacing) the test's environment for this process
        (``AMB_TRANSPORT=udp``).
    """

    def __init__(
        self,
        executable: str,
        log_dir: Path,
        params_file: Path | None = None,
        params: dict | None = None,
        extra_args: Sequence[str] = (),
        env: dict[str, str] | None = None,
    ) -> None:
        if executable.startswith("-m "):
            cmd = [sys.executable, "-m", executable[3:]]
            name = executable[3:].rsplit(".", 1)[-1]
        elif executable.endswith(".py"):
            cmd = [sys.executable, executable]
            name = Path(executable).stem
        else:
            path = INSTALL_LIB / executable
            if not path.exists():
                raise FileNotFoundError(f"{path} not built: run tools/bootstrap.sh")
            cmd = [str(path)]
            name = executable
        ros_args: list[str] = []
        if params_file is not None:
            ros_args += ["--params-file", str(params_file)]
        for key, value in (params or {}).items():
            ros_args += ["-p", f"{key}:={param_text(value)}"]
        ros_args += list(extra_args)
        if ros_args:
            cmd += ["--ros-args", *ros_args]
        self.cmd = cmd
        self.log_path = Path(log_dir) / f"{name}-{os.getpid()}-{time.monotonic_ns()}.log"
        self._log = open(self.log_path, "w")
        env = {**os.environ, **(env or {}), "PYTHONUNBUFFERED": "1"}
        # tied to the test process: a suite killed by its timeout leaves no node in the domain
        self.proc = subprocess.Popen(
            cmd,
            stdout=self._log,
            stderr=subprocess.STDOUT,
            env=env,
            preexec_fn=die_with_parent(),
        )

    @property
    def returncode(self) -> int | None:
        """Exit status, or None while running."""
        return self.proc.poll()

    def log(self) -> str:
        """Everything the process printed so far."""
        if not self._log.closed:
            self._log.flush()
        return self.log_path.read_text()

    def stop(self, sig: int = signal.SIGINT, timeout: float = 10.0) -> int:
        """Send ``sig``, wait up to ``timeout`` s, then SIGKILL; return the exit status."""
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
        self._log.close()
        return self.proc.returncode

    @property
    def name(self) -> str:
        """The executable's name (the log file's prefix)."""
        return self.log_path.name.split("-", 1)[0]

    def wait(self, timeout: float) -> int:
        """
        Wait for the process to exit by itself; return its status.

        Raises
        ------
        TimeoutError
            If it is still running after ``timeout`` s; the message ends with its log.
        """
        try:
            code = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            raise TimeoutError(
                f"{self.name} did not exit within {timeout} s; its log:\n{self.log()[-6000:]}"
            ) from None
        self._log.close()
        return code


def configuration_refusals(cases: list[tuple[str, NodeProcess, tuple[str, ...]]]) -> list[str]:
    """Check node processes that must refuse their configuration at start-up.

    Each case is ``(label, process, words)``: the process must exit with code 2 (the
    configuration-error exit of :func:`amb_tools.node_main.run_node`) and its
    ``[ERROR] configuration`` line must contain every word. Returns one line per failed case
    (empty if all refused as expected). Waits up to 240 s per process: start-up alone took
    7-20 s on a loaded 2-core machine.
    """
    failures = []
    for label, proc, words in cases:
        code = proc.wait(240)
        log = proc.log()
        line = next((x for x in log.splitlines() if "[ERROR] configuration" in x), "")
        missing = [w for w in words if w not in line]
        if code != 2 or missing:
            failures.append(f"{label}: exit {code}, missing {missing} in {line!r}\n{log[-800:]}")
    return failures
