"""``wavelet_controller``: wavelet-domain control of the rotor (thesis chapters 6-8) on ROS 2.

A thin ROS layer over :class:`amb_controller.pipeline.ControllerPipeline`. It reads
``/amb/measurement`` and ``/amb/wavelet/coefficients``, feeds the pipeline sample by sample in
index order, and at the last sample of every measured period m publishes exactly one
``ControlCommand`` for period ``m + delay_periods`` on ``/amb/control/command`` (zero force when
OFF, so the plant's lock-step loop keeps running) and a ``ControllerStatus`` on
``/amb/control/status``.

Both streams are subscribed ``raw`` and read with :mod:`amb_tools.cdr` (light views with the
messages' field names instead of rclpy message objects: the conversion of the nested
``CoefficientSet`` messages dominated this node's CPU at 67 Hz x 32 samples/rev).

Joining the two streams
-----------------------
Sample ``n`` is processed once its measurement and, for odd ``n``, its coefficients are in,
whatever order DDS delivered them in, so the commands equal the in-process runner's (``amb-sim``)
bit for bit: :class:`amb_controller.stream_join.StreamJoin` (ROS-free) holds the two streams and
releases the samples in index order; this node validates the messages, keeps the clocks and the
log, and feeds the pipeline with what the join releases.

Bad input and dead peers
------------------------
Measurements are validated (:func:`amb_tools.validation.check_measurement`) and sequenced
(:class:`amb_tools.validation.SampleSequencer`: repeats, stray indices and impossible stamps are
dropped; a confirmed gap or restart makes the pipeline answer the broken period with a held zero
command). Coefficient messages are rejected if their wavelet or ``samples_per_rev`` is not the
controller's, their sample index lies before the stream or more than eight periods ahead of it,
their stamp differs from their measurement's (these four by the join), or a set is malformed. If
the coefficients of a sample have not arrived ``coefficient_timeout`` wall seconds after the
later of its measurement and the last coefficient message accepted for an earlier sample (a dead
filterbank), the sample is processed without them: the period is answered with zero force, and
the lock-step loop keeps running on the PID. (A message for a later sample is no progress
towards this one: a filterbank restarted past it never sends it.) If neither a measurement nor a
coefficient message arrives for ``measurement_timeout`` s, the controller reports it and forgets
its history, so that it holds zero until the stream returns; it then resumes without a restart.
Coefficients that run ahead of the measurements while no measurement has come for
``measurement_timeout`` s mean the filterbank is fed and this node is not: the node says so once
per silence, as an error (the transport stopped feeding its reader, as seen after the process
was stopped for seconds, with shared memory or UDP; docs/history.md), and moves both stream
readers to a DDS participant of their own once no measurement has come for
``reader_renewal_after`` s while the measurement writer is still matched
(:class:`amb_tools.reader_participant.DeafReaders`; also when the coefficients are silent too, a
case the node cannot tell from a paused writer). A command the pipeline made with a non-finite
value (never expected) is replaced by a zero command. A period whose measurements carry
``STATUS_COMMAND_MISSING`` ran without the command sent for it (lost, late, or the plant's
watchdog): it is counted ``commands_late`` and the controller's step that made it is undone, so
that the integrators do not wind up (:mod:`amb_controller.supervisor`, "Commands the plant did
not apply"). All of it is counted on ``/diagnostics``.

Why the timeouts count from the last coefficient message: in lock-step the plant publishes a
period's samples at once and waits for the command, so a loaded filterbank that works through
them slowly (each coefficient message still following the last within a fraction of a second)
may deliver the period's last coefficients, and hold back the next measurements, longer than
either timeout after the period's measurements arrived. Counted from the measurement only,
such periods were answered with zero force (docs/controller_notes.md), a transient of the
rotor. Counted from the stream's progress, only a filterbank silent for
``coefficient_timeout`` (dead, or given no CPU for that long) is given up on: its last
message came before the measurement that waits. The default stays 1 s: the restart tests
(plant ``command_timeout`` 0.5 s) need a dead filterbank answered quickly.

Parameters
----------
Structural parameters are read-only. ``w``, ``v``, ``rate``, ``gain`` and ``force_limit`` may be
set at run time: the on-set callback validates the new set with ``ControllerConfig`` (the same
validation as at start-up, including the bearing capacity) and refuses it with the reason; an
accepted change is applied at the next period boundary (the controller is rebuilt from the model
in use and restarts its history, as on a mode change). ``measurement_timeout``,
``coefficient_timeout`` and ``status_period`` are node settings, also settable. The node
settings (:class:`~amb_controller.node_params.NodeSettings`) and the mapping of the ROS
parameters onto ``ControllerConfig`` are in :mod:`amb_controller.node_params`.

Services: ``/amb/control/set_mode`` (``SetControllerMode``),
``/amb/control/start_identification`` (``StartIdentification``; the identified model is written
to ``model_file_out`` or the request's ``model_file``). ``FaultEvent`` messages on
``/amb/fault/events`` trigger the configured fault actions (e.g. HOLD on auxiliary-bearing
contact). All parameters are validated at start-up (``ControllerConfig``): an invalid value
stops the node with exit status 2 and a message naming the parameter, the value and the range.

A controller whose closed loop on its own model has spectral radius ``max_model_radius`` (0.98)
or more is never set ACTIVE (:mod:`amb_controller.supervisor`, "A controller its own model says
diverges"): ``start_mode: active`` then logs the error and the node runs OFF (the configuration
is valid; the plant keeps its PID), a ``set_mode`` request is refused with the radius, and a
model or parameter change that makes a running controller unsafe switches it OFF. The status's
``message`` says why; ``/diagnostics`` carries ``closed_loop_radius``.
"""

from __future__ import annotations

import dataclasses
import time
from array import array
from pathlib import Path

import numpy as np
from amb_msgs.msg import (
    ControlCommand,
    ControllerStatus,
    FaultEvent,
    Measurement,
    WaveletCoefficients,
)
from amb_msgs.srv import SetControllerMode, StartIdentification
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message, serialize_message

from amb_common import topics
from amb_common.config_fields import default_of, parameter_fields
from amb_common.errors import RigError
from amb_common.faults import event_status
from amb_common.paths import config_file
from amb_common.rig import load_rig
from amb_controller.config import ControllerConfig
from amb_controller.early_messages import decision_message, model_change_message
from amb_controller.errors import ControllerValueError
from amb_controller.node_params import (
    PARAMETERS,
    START_MODES,
    TUNABLES,
    NodeSettings,
    config_from_parameters,
    parameter_descriptor,
    parameter_value,
    runtime_change,
)
from amb_controller.pipeline import ControllerPipeline
from amb_controller.selection import control_waveform
from amb_controller.stream_join import StreamJoin
from amb_controller.supervisor import Mode
from amb_controller.synthesis import ForceLimiter
from amb_tools.backlog import backlog_counts, declare_catch_up, gap_known
from amb_tools.cdr import CoefficientsView, MeasurementView, read_coefficients, read_measurement
from amb_tools.conversions import (
    MessageError,
    command_msg,
    controller_status_msg,
    stamp_seconds,
)
from amb_tools.local_bus import LocalBus, stream_publisher, stream_subscription
from amb_tools.node_main import ConfigurationError, run_node
from amb_tools.reader_participant import ClosesReaderParticipant, watch_readers
from amb_tools.streams import (
    COMMAND_QOS,
    FRAME_CODES,
    QUAD_CODES,
    STATUS_QOS,
    matched_subscribers,
    stream_qos,
)
from amb_tools.throttled_log import ThrottledWarnings
from amb_tools.validation import SampleSequencer, check_measurement
from amb_wavelet.frontend import FRAMES, QUADRATURES, ChannelFrontEnd
from amb_wavelet.messages import coefficient_records

#: What the node's error says when its measurement reader is no longer fed (module notes).
BLIND_READER = "the transport no longer feeds this node's measurement reader"


class WaveletControllerNode(ClosesReaderParticipant, Node):
    """The wavelet controller (module docstring)."""

    def __init__(self, bus: LocalBus | None = None) -> None:
        super().__init__("wavelet_controller")
        for cls in (ControllerConfig, NodeSettings):
            for f in parameter_fields(cls):
                default = parameter_value(f.name, default_of(f))
                self.declare_parameter(f.name, default, parameter_descriptor(f))
        self._configure()
        qos = stream_qos(self._pipe.samples_per_period)
        # composed: handed to the stack's own readers (the recorder) in process as well
        backlog = declare_catch_up(self)
        lossless = backlog.keeps_every_message  # lockstep: the recorder gets every one
        self._cmd_pub = stream_publisher(
            self, bus, ControlCommand, topics.COMMAND, COMMAND_QOS, lossless
        )
        self._status_pub = stream_publisher(
            self, bus, ControllerStatus, topics.STATUS, STATUS_QOS, lossless
        )
        self._readers = (
            stream_subscription(
                self, bus, Measurement, topics.MEASUREMENT, self._on_measurement, qos, backlog,
                urgent=True,
            ),
            stream_subscription(
                self, bus, WaveletCoefficients, topics.COEFFICIENTS, self._on_coefficients, qos,
                backlog.per_message(topics.SAMPLES_PER_COEFFICIENT_MESSAGE), urgent=True,
            ),
        )  # fmt: skip
        # composed with the fault monitor: its events in process, at once (urgent)
        self._fault_reader = stream_subscription(
            self, bus, FaultEvent, topics.FAULT_EVENTS,
            lambda raw: self._on_fault(deserialize_message(raw, FaultEvent)), QoSProfile(depth=10),
            urgent=True,
        )  # fmt: skip
        self.create_service(SetControllerMode, topics.SET_MODE, self._on_set_mode)
        self.create_service(StartIdentification, topics.START_IDENTIFICATION, self._on_identify)
        self._diag_pub = self.create_publisher(DiagnosticArray, topics.DIAGNOSTICS, 10)
        cfg = self._pipe.config
        self._join = StreamJoin(
            cfg.wavelet, self._pipe.samples_per_period, backlog.max_backlog,
            SampleSequencer(cfg.samples_per_rev), self._report,
        )  # fmt: skip
        self._last_wall: float | None = None  # arrival of the last valid measurement (monotonic)
        self._stale = False
        self._early_omega: float | None = -1.0  # the early action's model speed last logged
        self._blind_reported = False  # the error of a reader not fed (module notes), this silence
        self._pending_config: ControllerConfig | None = None
        # messages published, per topic (amb-run waits until its bag holds as many)
        self.commands_published = self.statuses_published = 0
        # the join counts what it refuses, gives up on and drops (coefficients_*, pending_*)
        self.counts = dict.fromkeys(
            ("measurements_rejected", "nonfinite_commands", "stalls", "config_changes"), 0
        )
        self._last_reason = ""
        self._warnings = ThrottledWarnings(self.get_logger(), period=5.0)
        # DDS readers only (composed, the streams come in process): moved to a participant of
        # their own when the transport stops feeding them (module notes)
        self._deaf = watch_readers(
            self, self._readers if bus is None else (), lambda: self._last_wall
        )
        self.create_timer(0.05, self._watchdog)
        self._status_timer = self.create_timer(
            self.get_parameter("status_period").value, self._publish_diagnostics
        )
        self.add_on_set_parameters_callback(self._on_set_parameters)

    def _configure(self) -> None:
        values = {name: self.get_parameter(name).value for name in PARAMETERS}
        rig_file = self.get_parameter("rig_file").value or str(config_file("rig.yaml"))
        try:
            rig = load_rig(rig_file)
        except RigError as exc:
            raise ConfigurationError(f"parameter 'rig_file' = {rig_file!r}: {exc}") from exc
        capacity = rig.amb.force_limit
        self._capacity = capacity
        try:
            config = ControllerConfig.from_dict(config_from_parameters(values), capacity)
            front = ChannelFrontEnd(config.samples_per_rev)
            self._pipe = ControllerPipeline(
                config, capacity, channel_labels=front.labels, probe_clearance=rig.probe_clearance
            )
        except (ControllerValueError, ValueError, OSError) as exc:
            raise ConfigurationError(str(exc)) from exc
        self._slots = [(FRAME_CODES[f], QUAD_CODES[q]) for f in FRAMES for q in QUADRATURES]
        start = self.get_parameter("start_mode").value
        if start not in START_MODES:
            raise ConfigurationError(f"parameter 'start_mode' = {start!r}: allowed {START_MODES}")
        self._identifying = False
        self._model_out = ""
        if start == "active":
            ok, why = self._pipe.set_mode(Mode.ACTIVE)
            if not ok and self._pipe.supervisor.unsafe_reason():
                # a valid configuration whose loop is unsafe: the plant keeps its PID and the
                # lock step its zero commands; status and log say why (supervisor docstring)
                self.get_logger().error(f"parameter 'start_mode' = 'active': {why}; staying OFF")
            elif not ok:
                raise ConfigurationError(f"parameter 'start_mode' = 'active': {why}")
        elif start == "identify":
            ok, why = self._pipe.start_identification()
            if not ok:
                raise ConfigurationError(f"parameter 'start_mode' = 'identify': {why}")
            self._identifying = True
            self.get_logger().info(why)
        model = self._pipe.model
        self.get_logger().info(
            f"{config.controller} controller, {config.wavelet}, levels p {list(config.levels)}, "
            f"delay {config.delay_periods}, mode {Mode(self._pipe.supervisor.mode).name}, "
            f"model {'none' if model is None else model.source}"
        )

    # ------------------------------------------------------------------ run-time parameters
    def _on_set_parameters(self, params) -> SetParametersResult:
        """Validate a run-time change with the start-up validation; keep the old on refusal."""
        # array-valued parameters arrive as array('d') / array('q'): plain lists for the config
        changes = {
            p.name: list(p.value) if isinstance(p.value, array | tuple) else p.value for p in params
        }
        values = {name: self.get_parameter(name).value for name in PARAMETERS}
        config, reason = runtime_change(changes, values, self._capacity)
        if reason is not None:
            return SetParametersResult(successful=False, reason=reason)
        if config is not None:
            self._pending_config = config
            tunable = {k: v for k, v in changes.items() if k in TUNABLES}
            self.get_logger().info(f"{tunable}: applied at the next period boundary")
        if "status_period" in changes:
            self._status_timer.cancel()
            self._status_timer = self.create_timer(
                changes["status_period"], self._publish_diagnostics
            )
        return SetParametersResult(successful=True)

    def _apply_pending_config(self) -> None:
        """At a period boundary: new limits and a controller rebuilt from the model in use."""
        config, self._pending_config = self._pending_config, None
        pipe = self._pipe
        pipe.config = config
        pipe.limiter = ForceLimiter(pipe.control, np.array(config.force_limit), pipe.capacity)
        pipe.supervisor.limiter = pipe.limiter
        if pipe.model is not None:
            running = pipe.supervisor.mode in (Mode.ACTIVE, Mode.HOLD)
            pipe.set_model(pipe.model)
            if running and pipe.supervisor.mode == Mode.OFF:
                self.get_logger().error(f"after the parameter change: {pipe.supervisor.message}")
        self.counts["config_changes"] += 1

    # ------------------------------------------------------------------ streams
    def _report(self, key: str, reason: str) -> None:
        """The status's reason and a throttled warning (the join's reports as well)."""
        self._last_reason = reason
        self._warnings.warning(key, reason)

    def _reject(self, counter: str, reason: str) -> None:
        self.counts[counter] += 1
        self._report(counter, reason)

    def _on_measurement(self, raw: bytes) -> None:
        try:
            msg = read_measurement(raw)
        except ValueError as exc:
            self._reject("measurements_rejected", f"unreadable measurement: {exc}; dropped")
            return
        try:
            check_measurement(msg, self._pipe.config.samples_per_rev)
        except MessageError as exc:
            self._reject("measurements_rejected", f"sample {msg.sample_index}: {exc}; dropped")
            return
        now = time.monotonic()
        self._last_wall = now
        self._blind_reported = False
        if self._stale:
            self._stale = False
            self.get_logger().info(f"measurements resumed at sample {msg.sample_index}")
        released = self._join.measurement(
            msg, stamp_seconds(msg.header.stamp), now, self._coefficient_timeout(),
            gap_known(self._readers[0]),
        )  # fmt: skip
        self._process_all(released)

    def _on_coefficients(self, raw: bytes) -> None:
        try:
            msg = read_coefficients(raw)
        except ValueError as exc:
            self._join.reject(f"unreadable coefficients: {exc}; dropped")
            return
        n = int(msg.sample_index)
        if self._join.beyond_horizon(n) and self._readers[0] is not None:
            # each reader takes its whole queue at a wake: the measurements of these
            # coefficients may be queued still, behind this wake (amb_tools.backlog)
            self._readers[0].poll()
            if self._join.beyond_horizon(n):
                self._report_blind_reader()
        self._process_all(
            self._join.coefficients(msg, time.monotonic(), self._coefficient_timeout())
        )

    def _coefficient_timeout(self) -> float:
        return self.get_parameter("coefficient_timeout").value

    def _drain(self, force: bool = False) -> None:
        """Process the samples the join releases now; ``force`` stops waiting for coefficients."""
        self._process_all(self._join.release(time.monotonic(), self._coefficient_timeout(), force))

    def _process_all(self, released: list[tuple[MeasurementView, CoefficientsView | None]]) -> None:
        for m, coeffs in released:
            self._process(m, coeffs)

    def _watchdog(self) -> None:
        if self._join.waiting:
            self._drain()  # a dead filterbank: stop waiting after coefficient_timeout
        if self._last_wall is None or self._stale:
            return
        # in lock-step the plant waits for our command: no measurement comes while the
        # filterbank works through a period, but its coefficients do (module notes)
        last = self._last_wall
        if self._join.last_coefficient is not None:
            last = max(last, self._join.last_coefficient[1])
        silent = time.monotonic() - last
        if silent > self.get_parameter("measurement_timeout").value:
            self._stale = True
            self.counts["stalls"] += 1
            self._drain(force=True)
            sup = self._pipe.supervisor
            if sup.controller is not None:
                sup.reset_controller()  # hold zero: no history carried across the silence
            self._last_reason = (
                f"no measurement for {silent:.2f} s after sample {self._join.last_processed}: "
                "holding zero until the stream returns"
            )
            self.get_logger().warning(self._last_reason)
            self._publish_diagnostics()

    def _report_blind_reader(self) -> None:
        """Say once per silence that the filterbank is fed and this node is not (module notes)."""
        timeout = self.get_parameter("measurement_timeout").value
        if self._blind_reported or self._last_wall is None:
            return
        if time.monotonic() - self._last_wall > timeout:
            self._blind_reported = True
            self.get_logger().error(
                f"no measurement for over {timeout:g} s while the filterbank's coefficients "
                f"still arrive: {BLIND_READER} (seen after this process was stopped for "
                "seconds; docs/history.md); its readers move to a new participant after "
                "reader_renewal_after s of silence"
            )

    def _process(self, m: MeasurementView, coeffs: CoefficientsView | None) -> None:
        records = []
        if coeffs is not None:
            try:
                records = coefficient_records(coeffs, self._slots)
            except MessageError as exc:
                self._pipe.count_rejected_input()
                self._join.reject(f"coefficients of sample {m.sample_index}: {exc}")
        command = self._pipe.on_sample(
            m.sample_index,
            records,
            m.displacement,
            m.rotor_speed,
            command_missing=bool(m.status & Measurement.STATUS_COMMAND_MISSING),
        )
        if command is None:
            return
        early = self._pipe.early
        if early is not None and early.model_omega != self._early_omega:
            self._early_omega = early.model_omega
            ok, text = model_change_message(early, m.rotor_speed)
            (self.get_logger().info if ok else self.get_logger().warning)(text)
        if self._pipe.early_detection is not None:
            active = self._pipe.supervisor.mode == Mode.ACTIVE
            self.get_logger().warning(decision_message(self._pipe.early_detection, active))
        cfg = self._pipe.config
        labels = self._pipe.control.labels
        n = self._pipe.samples_per_period
        header = m.header.to_msg()
        try:
            out = command_msg(command, header, labels, n, cfg.delay_periods, control_waveform(cfg))
        except MessageError as exc:
            self.counts["nonfinite_commands"] += 1
            self._last_reason = f"command for period {command.target_period}: {exc}; sent zero"
            self.get_logger().error(self._last_reason)
            zero = dataclasses.replace(
                command,
                coefficients=np.zeros_like(command.coefficients),
                force=np.zeros((4, n)),
                hold=True,
            )
            out = command_msg(zero, header, labels, n, cfg.delay_periods, control_waveform(cfg))
        self._cmd_pub.publish(serialize_message(out))
        self.commands_published += 1
        try:
            status = controller_status_msg(self._pipe.status(), header)
            self._status_pub.publish(serialize_message(status))
            self.statuses_published += 1
        except MessageError as exc:
            self._last_reason = f"status not published: {exc}"
        if self._pending_config is not None:
            self._apply_pending_config()
        if self._identifying and self._pipe.supervisor.mode != Mode.IDENTIFYING:
            self._identifying = False
            self._write_model()

    def _publish_diagnostics(self) -> None:
        status = self._pipe.status()
        seq = self._join.sequencer.counts
        counts = {**self.counts, **self._join.counts}
        problems = (
            any(counts[k] for k in counts if k != "config_changes")
            or any(seq[k] for k in ("stray", "stamp", "repeat"))
            or status["commands_late"] > 0  # the plant ran periods without our command
        )
        level = DiagnosticStatus.WARN if (problems or self._stale) else DiagnosticStatus.OK
        radius = self._pipe.supervisor.radius
        values = {
            "mode": Mode(status["mode"]).name,
            "closed_loop_radius": "none" if radius is None else f"{radius:.4f}",
            "measurements_stale": self._stale,
            "last_sample": self._join.last_processed,
            "commands_sent": status["commands_sent"],
            "commands_published": self.commands_published,
            "statuses_published": self.statuses_published,
            "commands_late": status["commands_late"],
            "commands_partial": status["commands_partial"],  # of those, applied from a sample on
            "callback_errors": getattr(self, "callback_errors", 0),
            "inputs_rejected": status["inputs_rejected"],
            **counts,
            "readers_renewed": self._deaf.renewals,
            **{f"samples_{k}": v for k, v in seq.items()},
            **matched_subscribers(self._cmd_pub, self._status_pub),
            **backlog_counts(*self._readers),
        }
        array = DiagnosticArray(
            status=[
                DiagnosticStatus(
                    level=level,
                    name=topics.diagnostic_name("wavelet_controller", self.get_namespace()),
                    message=self._last_reason or status["message"] or "ok",
                    values=[KeyValue(key=k, value=str(v)) for k, v in values.items()],
                )
            ]
        )
        array.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(array)

    def _write_model(self) -> None:
        path = self._model_out or self.get_parameter("model_file_out").value
        if self._pipe.model is None:
            self.get_logger().warning(
                f"identification ended without a model: {self._pipe.status()['message']}"
            )
            return
        if path:
            written = self._pipe.save_model(path)
            self.get_logger().info(f"identified model written to {written}")
        refusal = self._pipe.supervisor.unsafe_reason()
        if refusal:
            self.get_logger().error(f"identified model: ACTIVE will be refused: {refusal}")

    # ------------------------------------------------------------------ services, events
    def _on_fault(self, msg: FaultEvent) -> None:
        status, revised = event_status({kv.key: kv.value for kv in msg.evidence})
        action = self._pipe.on_fault(msg.fault_type, status, revised)
        what = f" ({status})" if status else ""
        self.get_logger().info(f"fault event type {msg.fault_type}{what}: {action}")

    def _on_set_mode(self, request, response):
        response.accepted, response.message = self._pipe.set_mode(request.mode)
        response.mode = int(self._pipe.supervisor.mode)
        if not response.accepted:
            self.get_logger().warning(f"set_mode {request.mode} refused: {response.message}")
        return response

    def _on_identify(self, request, response):
        axes = list(request.axes) or None
        ok, why = self._pipe.start_identification(
            axes,
            request.level or None,
            request.amplitude or None,
            request.periods_per_step or None,
        )
        response.accepted, response.message = ok, why
        if ok:
            self._identifying = True
            self._model_out = request.model_file
            if self._model_out and not Path(self._model_out).parent.exists():
                response.accepted = False
                response.message = f"model_file {self._model_out!r}: folder does not exist"
                self._pipe.set_mode(Mode.OFF)
                self._identifying = False
        return response


def main(args: list[str] | None = None) -> int:
    """Entry point of the ``wavelet_controller`` executable."""
    return run_node(WaveletControllerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
