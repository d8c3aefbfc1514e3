"""``plant_sim``: the simulated rig on ROS 2 (thesis chapter 2 model, chapter 3 faults).

A thin ROS layer over :class:`amb_plant_sim.simulator.PlantSimulator`. It publishes one
``Measurement`` per sample on ``/amb/measurement`` (only what a rig can measure), ``/clock``
(simulated time), and applies the wavelet control force of each ``ControlCommand`` during the
command's target period, in parallel with the local PID that the simulator runs (on a rig the
PID runs on the real-time board, so it belongs with the hardware side). A hardware I/O bridge
replaces this node by publishing and subscribing the same topics and types.

Run modes (ARCHITECTURE.md, "Time")
-----------------------------------
``lockstep`` (default)
    The plant owns simulated time. Control period ``k`` (samples ``k N .. k N + N - 1``,
    ``N = samples_per_period``) starts only when the command whose ``period_index`` is ``k``
    has arrived, for ``k >= delay_periods``; the first ``delay_periods`` periods run with zero
    wavelet force, since no measured period precedes them. The controller answers every measured
    period ``m`` with one command for ``m + delay_periods`` (zero force when it is OFF), so the
    loop sustains itself and its results do not depend on machine speed. A command that has not
    arrived ``command_timeout`` wall seconds after the period could start is declared missing:
    logged, counted, and the period runs with zero wavelet force (the rotor stays on its PID).
``realtime``
    Samples are produced on the wall clock (times ``time_scale``); a command is applied if it
    arrived before its period starts, else the period runs with zero force and the command is
    counted late (a command already queued at the reader when the period starts is taken then,
    before the period is simulated, and counted as ``taken_at_start``). With ``partial_commands``
    (default) a period that starts without its command is simulated a sample at a time as its
    samples fall due, and a command that arrives before the period ends is applied to the samples
    still ahead (counted ``partial`` as well as ``late``; the samples before it carry
    ``STATUS_COMMAND_MISSING``): a command a fraction of a period late acts on the rest of its
    period instead of leaving all of it on PID. This is how a rig behaves:
    each period is simulated when it starts (its wavelet force is fixed then; the first one just
    before the clock starts, so that its cold start is not taken from the first periods) and each of
    its samples is published at its own instant, from a timer at the sample interval, so that the
    last sample of a period leaves at the period's end and the command latency (``latency_summary``)
    is measured from there. The effective control delay is reported as well (``control_summary``):
    the fraction of the periods that could have a command which ran with one, and, for each command,
    its arrival minus the wall time its period started (negative: in time; the lead a rig has left).
    So is the plant's own punctuality: at each wake that publishes, how long after its instant the
    oldest sample left (``sample publication lag``, p99 and max): a late command after a plant
    stall is the plant's, not the nodes'. Its longest single measurement write is reported too:
    a reader process stopped or descheduled while it holds its shared-memory port holds the
    write (:mod:`amb_tools.lossless`).

A command is rejected (counted, reported, never applied) if its period has already started
(``late``), if it is malformed (:func:`amb_tools.validation.check_command`: sizes, indices,
non-finite force), if it was made for another ``delay_periods`` than the plant's (controller and
plant disagree on i, eq. 8.10), if it repeats a period already commanded (the first is kept), if
it is stamped after the last published sample or based on a period not yet measured (from the
future), or if it targets a period more than ``delay_periods + 16`` periods ahead (nothing sane
computes that far ahead; it would only fill memory). Forces beyond ``wavelet_force_limit`` are
clipped to it and counted.

Command watchdog
----------------
A period with no command runs with zero wavelet force (the rotor stays on the PID) and its
samples carry ``STATUS_COMMAND_MISSING``. In lockstep the first missing command costs
``command_timeout`` wall seconds; the plant then declares the controller lost
(``STATUS_WATCHDOG`` on every sample, ``controller_lost`` on ``/diagnostics``) and, until a
valid command arrives again, waits at most one period of real time for each command, i.e. it
runs on PID at the real-time pace. The first valid command ends the watchdog: lockstep resumes
from its target period without a restart of either node.

Run-time parameters
-------------------
``command_timeout``, ``wavelet_force_limit`` (0 < limit <= the rig's bearing capacity),
``time_scale`` and ``status_period`` may be set at run time; the on-set callback refuses an
invalid value with the reason (the old value stays) and an accepted one is applied at the next
period boundary. Every other parameter is read-only (rclpy's refusal names it).

The run lasts a whole number of control periods, ``round(duration * fs / N)`` (the in-process
runner ``amb-sim`` runs the same). When it is over the node waits until every subscriber has
acknowledged the last measurement, reports, and exits with status 0 (``exit_at_end``).
"""

from __future__ import annotations

import math
import time
from collections import deque

import numpy as np
import yaml
from amb_msgs.msg import ControlCommand, Measurement
from amb_msgs.srv import InjectFault
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import (
    SetParametersResult,
)
from rclpy.duration import Duration
from rclpy.node import Node
from rosgraph_msgs.msg import Clock

from amb_common import topics
from amb_common.names import N_AXES
from amb_plant_sim import node_params
from amb_plant_sim.command_book import SPREAD_HISTORY, CommandBook, CommandOffer, spread
from amb_plant_sim.errors import ScenarioError, SimulationError
from amb_plant_sim.node_params import RUNTIME_PARAMETERS
from amb_plant_sim.simulator import MeasurementBlock
from amb_tools import lossless
from amb_tools.conversions import MessageError, measurement_bytes, stamp, stamp_seconds
from amb_tools.node_main import run_node
from amb_tools.reader_participant import ClosesReaderParticipant, MovableSubscription, watch_readers
from amb_tools.streams import COMMAND_QOS, matched_subscribers, stream_qos
from amb_tools.throttled_log import ThrottledWarnings
from amb_tools.validation import check_command


class PlantSimNode(ClosesReaderParticipant, Node):
    """The simulated rig (module docstring)."""

    def __init__(self) -> None:
        super().__init__("plant_sim")
        node_params.declare(self)
        self._configure(node_params.configure(node_params.settings(self)))
        # lockstep: every sample reaches every reader, a slow one (the recorder) pacing the loop
        self._meas_pub = lossless.publisher(
            self, Measurement, topics.MEASUREMENT, stream_qos(self._N), self._mode == "lockstep"
        )
        self._clock_pub = self.create_publisher(Clock, topics.CLOCK, 10)
        self._diag_pub = self.create_publisher(DiagnosticArray, topics.DIAGNOSTICS, 10)
        self._cmd_reader = MovableSubscription(
            self, ControlCommand, topics.COMMAND, self._on_command, COMMAND_QOS
        )
        self.commands_received = 0
        # moved to a participant of its own when the transport stops feeding it
        # (amb_tools.reader_participant: a controller stopped for seconds met it)
        self._deaf = watch_readers(self, [self._cmd_reader], lambda: self.commands_received)
        self.create_service(InjectFault, topics.INJECT_FAULT, self._on_inject)
        self._status_timer = self.create_timer(
            self.get_parameter("status_period").value, self._publish_status
        )
        # lockstep: a poll (commands also step the loop); realtime: the wall-clock sample timer
        tick = 0.002 if self._mode == "lockstep" else max(1.0 / self._sim.fs, 2.0e-4)
        self._timer = self.create_timer(tick, self._tick)
        self._outbox: deque[tuple[float, int, bytes]] = deque()  # realtime: (t, index, CDR)
        # realtime: at each wake that publishes, how far behind its instant the oldest sample
        # left (simulated s): the plant's (a bridge's) own stalls, apart from the nodes'
        self._publication_lag: deque[float] = deque(maxlen=SPREAD_HISTORY)
        # wall s of the longest measurement write: a write held by a reader's shared-memory
        # port (amb_tools.lossless, module notes) delays the samples after it
        self._write_max = 0.0
        self._book = CommandBook(
            self._delay,
            self._force_limit,
            self._mode == "realtime",
            partial=self.get_parameter("partial_commands").value,
        )
        self.counts = self._book.counts
        self._controller_lost = False
        self._resume_from = 0
        self._last_stamp = -1.0
        self._pending_parameters: dict[str, float] = {}
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._last_reason = ""
        self._warnings = ThrottledWarnings(self.get_logger(), period=2.0)
        self._started = False
        self._startup_deadline = time.monotonic() + self.get_parameter("startup_timeout").value
        self._waiting_since: float | None = None
        self._polling = False  # the command reader is being polled: _on_command steps nothing
        self._wall0 = 0.0
        self.run_window: tuple[float, float] | None = None  # (first, last sample), monotonic s
        self.done = False
        self.get_logger().info(
            f"{self._scenario.name}: {self._sim.omega / (2 * math.pi):.3f} Hz, "
            f"{self._spr} samples/rev ({self._sim.fs:.1f} Hz), {self._duration} s, "
            f"mode {self._mode}"
        )

    # ------------------------------------------------------------------ configuration
    def _configure(self, run: node_params.PlantRun) -> None:
        self._N = run.samples_per_period
        self._mode = run.settings.mode
        self._force_limit = run.force_limit
        self._delay = run.settings.delay_periods
        self._timeout = run.settings.command_timeout
        self._clock_every = run.settings.clock_every
        self._spr = run.samples_per_rev
        self._scenario = run.scenario
        self._duration = run.scenario.duration
        self._sim = run.simulator
        self._n_total = run.n_total

    # ------------------------------------------------------------------ commands
    def _on_command(self, msg: ControlCommand) -> None:
        self.commands_received += 1
        try:
            force, malformed = check_command(msg, self._N), None  # (N, 4) N
        except MessageError as exc:
            force, malformed = None, str(exc)
        offer = CommandOffer(
            period_index=msg.period_index,
            delay_periods=msg.delay_periods,
            based_on_period=msg.based_on_period,
            stamp=stamp_seconds(msg.header.stamp),
            force=force,
            malformed=malformed,
        )
        n = self._sim.sample_index
        # a period running without its command (partial_commands) has started: count from the next
        next_period = -(-n // self._N) if self._book.open_period is not None else n // self._N
        reason = self._book.offer(offer, next_period, self._last_stamp, time.monotonic())
        if reason is not None:
            self._last_reason = reason
            late = msg.period_index < next_period
            self._warnings.warning("late" if late else "rejected", reason)
            return
        if self._controller_lost:
            self._controller_lost = False
            self._resume_from = msg.period_index
            self._last_reason = (
                f"commands resumed with period {msg.period_index}: lockstep from there"
            )
            self.get_logger().info(self._last_reason)
        if self._mode == "lockstep" and not self._polling:
            self._tick()

    def _poll_commands(self) -> None:
        """Take the commands queued in the reader now, before the executor hands them over.

        The executor hands over one command per new-message event of the middleware; a command
        queued with no event standing for it would wait there until the next one's, a period
        late, and so would every later command (docs/history.md).
        """
        self._polling = True
        try:
            self._cmd_reader.poll()
        finally:
            self._polling = False

    # ------------------------------------------------------------------ run-time parameters
    def _on_set_parameters(self, params) -> SetParametersResult:
        """Validate run-time changes (the old value stays on refusal); apply at a boundary."""
        changes = {}
        for param in params:
            if param.name not in RUNTIME_PARAMETERS:
                continue  # read-only ones never get here (rclpy refuses them, naming them)
            value = param.value
            if param.name == "wavelet_force_limit":
                capacity = self._sim.rig.amb.force_limit
                if not (isinstance(value, float) and 0.0 <= value <= capacity):
                    return SetParametersResult(
                        successful=False,
                        reason=f"parameter 'wavelet_force_limit' = {value!r} N: expected "
                        f"0 (= capacity) .. {capacity} N, the bearing capacity (rig file "
                        "amb.force_limit)",
                    )
                value = value or capacity
            changes[param.name] = value
        if "status_period" in changes:
            self._status_timer.cancel()
            self._status_timer = self.create_timer(
                changes.pop("status_period"), self._publish_status
            )
        self._pending_parameters.update(changes)
        return SetParametersResult(successful=True)

    def _apply_parameters(self) -> None:
        changes, self._pending_parameters = self._pending_parameters, {}
        if "command_timeout" in changes:
            self._timeout = changes["command_timeout"]
        if "wavelet_force_limit" in changes:
            self._book.force_limit = changes["wavelet_force_limit"]
        self.counts["parameter_changes"] += len(changes)
        if changes:
            self.get_logger().info(f"applied at sample {self._sim.sample_index}: {changes}")

    # ------------------------------------------------------------------ stepping
    def _tick(self) -> None:
        if self.done:
            return
        if not self._started:
            want = self.get_parameter("wait_for_subscribers").value
            # lockstep also needs the command publisher matched, or the first command is lost
            cmd = self._cmd_reader.subscription
            commander = self._mode != "lockstep" or cmd.get_publisher_count() > 0
            if self._meas_pub.get_subscription_count() < want or not commander:
                if time.monotonic() < self._startup_deadline:
                    return
                self.get_logger().warning(
                    f"{self._meas_pub.get_subscription_count()} of {want} subscribers of "
                    f"{self._meas_pub.topic_name}, {cmd.get_publisher_count()} "
                    f"publishers of {cmd.topic_name} after startup_timeout: starting anyway"
                )
            self._started = True
            if self._mode == "realtime" and self._remaining() > 0:
                # the first period, simulated before the clock starts: its first run takes tens
                # of ms (the speed's discretisation, cold code paths; 35 ms at 67 Hz x 32), which
                # put the first periods behind their instants (a burst at the start, their
                # commands late); a rig's I/O has no such start-up
                self._run_period(0)
            self._wall0 = time.monotonic()
        if self._mode == "lockstep":
            self._tick_lockstep()
        else:
            self._tick_realtime()

    def _remaining(self) -> int:
        if self._n_total is not None:
            return self._n_total - self._sim.sample_index
        return 1 if self._sim.time < self._duration else 0

    def _tick_lockstep(self) -> None:
        for _ in range(64):  # bounded work per callback: let the executor breathe
            if self._remaining() <= 0:
                self._finish()
                return
            k = self._sim.sample_index // self._N
            if k >= max(self._delay, self._resume_from) and k not in self._book:
                self._poll_commands()
                if k in self._book:
                    continue
                now = time.monotonic()
                if self._waiting_since is None:
                    self._waiting_since = now
                wait = self._timeout
                if self._controller_lost:  # PID at the real-time pace until commands return
                    wait = min(wait, self._N / self._sim.fs)
                if now - self._waiting_since < wait:
                    return
                self.counts["missing"] += 1
                if not self._controller_lost:
                    self._controller_lost = True
                    self.counts["watchdog_trips"] += 1
                    self._last_reason = (
                        f"no command for period {k} within {self._timeout} s: controller lost, "
                        "zero wavelet force (PID only) until commands return"
                    )
                    self.get_logger().warning(self._last_reason)
                    self._publish_status()
            elif k >= self._delay and k not in self._book:
                self.counts["missing"] += 1  # between the watchdog and the first new command
            self._waiting_since = None
            self._run_period(k)

    def _tick_realtime(self) -> None:
        due = (time.monotonic() - self._wall0) * self.get_parameter("time_scale").value
        if self._outbox and self._outbox[0][0] <= due:  # the oldest due sample: how late it goes
            self._publication_lag.append(due - self._outbox[0][0])
        while True:
            while self._outbox and self._outbox[0][0] <= due:
                self._release(*self._outbox.popleft())
            if self._outbox or self._remaining() <= 0 or self._sim.time > due:
                break
            n0 = self._sim.sample_index
            if n0 % self._N and self._book.open_period == n0 // self._N:
                self._run_open(n0 // self._N, due)  # its samples due now, or its late command
            else:
                self._run_period(n0 // self._N, due)  # the period starts: simulate it
        if self._remaining() <= 0 and not self._outbox:
            self._finish()

    def _run_period(self, k: int, due: float | None = None) -> None:
        """Simulate period ``k`` from its next sample (realtime: ``due``, simulated s, is now)."""
        if self._pending_parameters and self._sim.sample_index % self._N == 0:
            self._apply_parameters()
        n0 = self._sim.sample_index
        n = min(self._N - n0 % self._N, max(self._remaining(), 1))
        now = None
        if self._mode == "realtime" and n0 % self._N == 0:
            # a command already in the reader's queue is in time: take it before the period
            # starts (the executor may hand this timer over before the command's callback)
            queued = k in self._book
            self._poll_commands()
            self.counts["taken_at_start"] += not queued and k in self._book
            now = time.monotonic()
        force = self._book.take(k, now)
        if force is None:
            missing = k >= self._delay  # the first `delay` periods have no command by design
            if missing and self._mode == "realtime":
                self.counts["missing"] += 1
                if not self._controller_lost:
                    self._controller_lost = True
                    self.counts["watchdog_trips"] += 1
            if self._book.open_period == k and due is not None:
                n = self._due_samples(n, due)  # the rest as it falls due (_run_open)
            wf, status = self._without_command(n, missing)
        else:
            wf, status = force[n0 % self._N : n0 % self._N + n], 0
        block = self._sim.advance(n, wf)
        self._publish(block, wf, status)

    def _due_samples(self, n: int, due: float) -> int:
        """How many of the next ``n`` samples are due at simulated time ``due`` (at least 1)."""
        behind = math.floor((due - self._sim.time) * self._sim.fs + 1e-9) + 1
        return max(1, min(n, behind))

    def _run_open(self, k: int, due: float) -> None:
        """Go on with period ``k``, started without its command: the rest with it if it came.

        The samples before the command ran with zero wavelet force and carry
        ``STATUS_COMMAND_MISSING``; from the command on they carry no flag (the module
        docstring, ``partial_commands``).
        """
        n0 = self._sim.sample_index
        position = n0 % self._N
        n = min(self._N - position, max(self._remaining(), 1))
        self._poll_commands()
        force = self._book.take_rest(k, position)
        if force is not None:
            wf, status = force[:n], 0
            if self._controller_lost:
                self._controller_lost = False
                self._last_reason = (
                    f"commands resumed with period {k} (applied from its sample {position})"
                )
                # one per late command under a sustained overload: throttled as the warnings
                self.get_logger().info(self._last_reason, throttle_duration_sec=2.0)
        else:
            wf, status = self._without_command(self._due_samples(n, due), missing=True)
        block = self._sim.advance(len(wf), wf)
        self._publish(block, wf, status)

    def _without_command(self, n: int, missing: bool) -> tuple[np.ndarray, int]:
        """Zero wavelet force for ``n`` samples, and their flags.

        ``STATUS_COMMAND_MISSING`` if a command was due (``missing``), ``STATUS_WATCHDOG`` while
        the controller is taken as lost.
        """
        status = Measurement.STATUS_COMMAND_MISSING if missing else 0
        if self._controller_lost:
            status |= Measurement.STATUS_WATCHDOG
        return np.zeros((n, N_AXES)), status

    def _publish(self, block: MeasurementBlock, wf: np.ndarray, status: int) -> None:
        limit = self._sim.rig.amb.force_limit
        # serialised in one go (amb_tools.cdr): the same messages as measurement_msgs builds
        messages, flags = measurement_bytes(block, wf, status, self._spr, limit)
        self.counts["saturated_samples"] += int(
            np.count_nonzero(flags & Measurement.STATUS_FORCE_SATURATED)
        )
        samples = zip(block.time.tolist(), block.sample_index.tolist(), messages, strict=True)
        if self._mode == "realtime":
            self._outbox.extend(samples)  # released at their instants by _tick_realtime
            return
        for sample in samples:
            self._release(*sample)

    def _release(self, t: float, index: int, raw: bytes) -> None:
        """Publish one serialised sample (and ``/clock``); a period's last one starts latency."""
        start = time.monotonic()
        self._meas_pub.publish(raw)
        self._write_max = max(self._write_max, time.monotonic() - start)
        if index % self._clock_every == 0:
            self._clock_pub.publish(Clock(clock=stamp(t)))
        self._last_stamp = t
        if index % self._N == self._N - 1:
            self._book.period_sent(index // self._N, time.monotonic())

    def latency_summary(self) -> dict[str, float]:
        """Wall latency from a period's last sample to the command based on it, s.

        See :meth:`amb_plant_sim.command_book.CommandBook.latency_summary`.
        """
        return self._book.latency_summary()

    def control_summary(self) -> dict[str, float]:
        """The effective control delay: periods controlled, command arrival - period start.

        See :meth:`amb_plant_sim.command_book.CommandBook.control_summary`.
        """
        return self._book.control_summary(-(-self._sim.sample_index // self._N))

    def _finish(self) -> None:
        if self.done:
            return
        # the run's wall time ends with its last sample: the acknowledgements waited for below
        # can take a reliable writer's heartbeat period (3 s with Fast DDS's defaults, seen in
        # half of the 4 s runs of bench/pipeline_profile.py, halving the reported factor; 20 ms
        # with the nodes' profile, amb_tools.transport_profile)
        self.run_window = (self._wall0, time.monotonic())  # node_main's CPU log (bench/)
        wall = self.run_window[1] - self._wall0
        self._meas_pub.wait_for_all_acked(Duration(seconds=10.0))
        self._publish_status()
        # the last report (done, sample_index) tells amb-run how far the consumers must get
        self._diag_pub.wait_for_all_acked(Duration(seconds=2.0))
        control = self._book.report(-(-self._sim.sample_index // self._N), self._N / self._sim.fs)
        if self._publication_lag:  # realtime
            lag = spread(self._publication_lag)
            control += (
                f"; sample publication lag p99 {lag['p99'] * 1e3:.2f} ms, "
                f"max {lag['max'] * 1e3:.2f} ms; longest measurement write "
                f"{self._write_max * 1e3:.2f} ms"
            )
        waits = getattr(self._meas_pub, "waits", 0)  # lockstep (amb_tools.lossless)
        if waits:
            control += (
                f"; measurements held {self._meas_pub.waited_s:.2f} s in {waits} waits for a "
                "reader behind by the writer's history"
            )
        self.get_logger().info(
            f"scenario {self._scenario.name} complete at t = {self._sim.time:.4f} s "
            f"({self._sim.sample_index} samples) in {wall:.2f} s wall, real-time factor "
            f"{self._sim.time / wall:.2f}{control}; commands: "
            + ", ".join(f"{k} {v}" for k, v in self.counts.items())
        )
        if self.get_parameter("exit_at_end").value:
            self.done = True
        else:
            self._timer.cancel()

    # ------------------------------------------------------------------ service, status
    def _on_inject(self, request: InjectFault.Request, response: InjectFault.Response):
        try:
            event = yaml.safe_load(request.event_yaml)
            if not isinstance(event, dict):
                raise ScenarioError(f"event_yaml must be a mapping, got {type(event).__name__}")
            if event.get("time") is None or event["time"] < self._sim.time:
                event["time"] = self._sim.time
            injected = self._sim.inject(event)
        except (yaml.YAMLError, ScenarioError, SimulationError, ValueError, TypeError) as exc:
            response.accepted = False
            response.message = str(exc)
            return response
        response.accepted = True
        response.scheduled_time = float(injected.time)
        response.message = f"{injected.kind} scheduled at t = {injected.time:.4f} s"
        self.get_logger().info(response.message)
        return response

    def _publish_status(self) -> None:
        level = DiagnosticStatus.OK
        if self.counts["missing"] or self.counts["late"] or self.counts["rejected"]:
            level = DiagnosticStatus.WARN
        if self._controller_lost:
            level = DiagnosticStatus.ERROR
        values = {
            "time": f"{self._sim.time:.6f}",
            "sample_index": self._sim.sample_index,
            # realtime simulates each period at its start: the last sample published so far
            # is behind the simulated ``time`` by up to a period (-1: none yet)
            "published_time": f"{self._last_stamp:.6f}",
            "speed_hz": f"{self._sim.omega / (2 * math.pi):.4f}",
            "done": self.done or self._remaining() <= 0,
            "controller_lost": self._controller_lost,
            "readers_renewed": self._deaf.renewals,
            "callback_errors": getattr(self, "callback_errors", 0),
            **self.counts,
            **matched_subscribers(self._meas_pub),
        }
        status = DiagnosticStatus(
            level=level,
            name=topics.diagnostic_name("plant_sim", self.get_namespace()),
            message=self._last_reason or "ok",
            hardware_id=self._scenario.name,
            values=[KeyValue(key=k, value=str(v)) for k, v in values.items()],
        )
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(array)


def main(args: list[str] | None = None) -> int:
    """Entry point of the ``plant_sim`` executable."""
    return run_node(PlantSimNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
