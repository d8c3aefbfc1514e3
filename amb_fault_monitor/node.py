"""``fault_monitor``: wavelet coefficients in, fault events and diagnostics out (thesis ch. 5).

A thin ROS layer over :class:`amb_fault_monitor.monitor.FaultMonitor`. Each
``WaveletCoefficients`` message becomes one
:class:`~amb_fault_monitor.records.SampleCoefficients`; the events the core decides are
numbered and written to the JSON-lines event log (``event_log`` parameter, reloaded at start
with its contact counters) and published as ``amb_msgs/FaultEvent`` on ``/amb/fault/events``.
``Measurement`` messages give the monitor the wavelet force applied in each sample
(``wavelet_force``, :meth:`~amb_fault_monitor.monitor.FaultMonitor.control_force`): a
transient that a step of it explains (``control_step``, N per axis from one revolution to the
next; the monitor's module notes, step 5) is no event but counted on ``/diagnostics``
(``control_transients``, ``last_control_transient``, ``control_step_n`` in use; the monitor
status turns WARN with the message "transient from control action ..."), and their currents:
a measured control current (``current``) that departs from the demand (``bearing_force`` over
``K_i`` of the rig file) for a quarter revolution is a ``COIL_FAILURE`` event naming the AMB
and the axis (:mod:`amb_fault_monitor.coil_check`; the rotor's response to it is counted as
``coil_explained``, its contacts reported). They also feed two
trips per plane with hysteresis (:mod:`amb_fault_monitor.trips`): the radial displacement and
the 1 x orbit semi-major axis over the last revolution. Their levels default to fractions
(``trip_displacement_fraction``, ``trip_1x_fraction``) of the clearance of the nearest
clearance bearing read from the rig file (``rig`` parameter, default ``config/rig.yaml``);
``trip_displacement`` / ``trip_1x`` > 0 override them in m. A trip is an ERROR on
``/diagnostics`` and a ``TRIP`` event. ``/diagnostics`` carries one status per sensor plane
(OK / WARN while an episode is open / ERROR when tripped) and one for the monitor, whose
``last_sample`` and ``last_coefficient_sample`` are the indices of the last measurement and
coefficient message processed (``amb-run`` stops the monitor only once they reach the plant's
last sample).

Both streams are taken as raw CDR and read with :mod:`amb_tools.cdr` (no rclpy message objects
per sample). Black box (``blackbox_dir`` non-empty): every accepted measurement and coefficient
message goes, as received (CDR), into a ring buffer of
``blackbox_pre_s`` seconds; at each event ``blackbox_post_s`` more seconds are captured and the
lot written to its own bag ``blackbox_dir/event_<id>_<TYPE>`` (topic names as subscribed).

Stamps: the coefficient message carries the stamp of its completing sample; the onset and
detection stamps are back-dated from it by ``(sample_index - n) / fs`` at the current speed.

Bad input (issue 8)
-------------------
Measurements are validated (:func:`amb_tools.validation.check_measurement`: array lengths,
finite values, ``rotor_speed`` > 0, ``rotor_angle`` in [0, 2 pi), ``samples_per_rev``) and
sequenced (:class:`amb_tools.validation.SampleSequencer`: repeats, stray indices and stamps
going back or from the future are dropped; a confirmed gap or restart empties the 1 x window).
Coefficient messages are validated by
:func:`~amb_fault_monitor.coefficient_messages.check_coefficients` (``samples_per_rev``, known
level, kind, frame and quadrature codes, 8 finite values per set, a support ending at the
message's sample) and sequenced the same way: the finest level completes a coefficient every
second sample (fig. 4.3), so ``sample_index // 2`` of consecutive messages is consecutive and
the coefficient stream is a :class:`~amb_tools.validation.SampleSequencer` stream at half the
sample rate. A confirmed gap or restart of the coefficient stream (a filterbank or plant
restarted, samples lost) resets the monitor, which calibrates again: its change features
compare coefficients a revolution apart and must not straddle a discontinuity. Nothing
rejected reaches the trips, the monitor or the black box; every rejection is counted by kind
on the monitor's ``/diagnostics`` status (``measurements_rejected``, ``coefficients_rejected``,
``samples_*``, ``coefficients_*``), which turns WARN. The monitor is not in the lock-step loop
and may fall behind on a loaded machine: its subscriptions queue :data:`QUEUE_REVS` revolutions
of messages, so that it lags rather than loses (a loss would be a gap, and a recalibration).
In ``realtime`` a lag has a bound, ``max_backlog`` measurements, queued or by age
(:mod:`amb_tools.backlog`; 0, the default, none): beyond it the oldest are dropped, one counted
gap per overload, so that the
monitor's decisions stay current instead of trailing the rotor by seconds.

Parameters
----------
Structural parameters are read-only. ``trip_displacement``, ``trip_displacement_fraction``,
``trip_1x``, ``trip_1x_fraction``, ``trip_hysteresis``, ``control_step`` and ``status_period``
may be set at run time: the on-set callback checks the whole change (finite, in the declared
range, trip levels computable) and refuses it with a reason naming the parameter, the value and
the range (the old values stay); the post-set callback applies it. At start-up an out-of-range
or mistyped value, an unknown frame, a level the filterbank cannot publish, a missing or
malformed rig file or event log stop the node with exit status 2 and the same kind of message
(:class:`amb_tools.node_main.ConfigurationError`). The monitor's parameters are the parameter
fields of :class:`~amb_fault_monitor.config.MonitorConfig`, the node's own those of
:class:`~amb_fault_monitor.node_params.NodeSettings`: each field holds its default, description,
range and whether it may change at run time (:mod:`amb_fault_monitor.node_params`).
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np
import yaml
from amb_msgs.msg import FaultEvent as FaultEventMsg
from amb_msgs.msg import Measurement, WaveletCoefficients
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message

from amb_common import topics
from amb_common.errors import RigError
from amb_common.faults import FaultEvent
from amb_common.rig import load_rig
from amb_fault_monitor.blackbox import BlackBox
from amb_fault_monitor.coefficient_hold import CoefficientHold
from amb_fault_monitor.coefficient_messages import (
    EXTRA_OCTAVES,
    FRAME,
    check_coefficients,
    filterbank_restarted,
    record_from_msg,
)
from amb_fault_monitor.config import MonitorConfig
from amb_fault_monitor.errors import FaultMonitorError, RecordError
from amb_fault_monitor.event_log import EventLog
from amb_fault_monitor.monitor import FaultMonitor
from amb_fault_monitor.node_params import (
    MONITOR_PARAMETERS,
    MONITOR_RUNTIME,
    NODE_PARAMETERS,
    RUNTIME,
    check_runtime_value,
    parameter_descriptor,
    parameter_value,
)
from amb_fault_monitor.trips import PlaneTrips, clearance_levels
from amb_tools.backlog import BacklogReader, backlog_counts, declare_catch_up, gap_known
from amb_tools.cdr import (
    CoefficientsView,
    MeasurementView,
    StampView,
    read_coefficients,
    read_measurement,
)
from amb_tools.conversions import (
    MessageError,
    from_float_array,
    stamp,
    stamp_seconds,
)
from amb_tools.local_bus import LocalBus, stream_publisher, stream_subscription
from amb_tools.node_main import ConfigurationError, run_node
from amb_tools.reader_participant import ClosesReaderParticipant, watch_readers
from amb_tools.streams import matched_subscribers, stream_qos
from amb_tools.throttled_log import ThrottledWarnings
from amb_tools.validation import SampleSequencer, check_measurement
from amb_wavelet.levels import revolution_level

#: rad/s used for the stamp check of coefficients before any measurement gave the speed: the
#: expected step is then huge, so only stamps going back are refused.
UNKNOWN_OMEGA = 1e-9
#: Revolutions of messages the subscriptions queue: the monitor is not in the lock-step loop, so
#: on a loaded machine it may fall seconds behind the plant; a lost message would be a gap, and a
#: gap costs a new calibration (docs/history.md, "Fault monitor queue").
QUEUE_REVS = 256
#: Sequencer counts of refused messages (the others, gaps and restarts, are confirmed changes).
REFUSED = ("repeat", "stray", "stamp")
# s (wall): held coefficients are processed without their measurements at the next status once
# no measurement has come in this long (the stream stopped: lost, not late; _deliver)
HELD_TIMEOUT = 1.0


class FaultMonitorNode(ClosesReaderParticipant, Node):
    """Publish fault events classified from the wavelet coefficients (module docstring)."""

    def __init__(self, bus: LocalBus | None = None) -> None:
        super().__init__("fault_monitor")
        for f in (*MONITOR_PARAMETERS, *NODE_PARAMETERS):
            self._declare(f.name, parameter_value(f), parameter_descriptor(f))
        p = self.get_parameter
        self._spr = p("samples_per_rev").value
        levels = self._levels(list(p("levels").value))
        frames = tuple(p("frames").value)
        if not frames or any(f not in FRAME.values() for f in frames):
            raise ConfigurationError(
                f"parameter 'frames' = {list(frames)}: expected a non-empty subset of "
                f"{list(FRAME.values())}"
            )
        values = {f.name: p(f.name).value for f in MONITOR_PARAMETERS}
        values.update(levels=levels, frames=frames)
        try:
            config = MonitorConfig(**values)
        except FaultMonitorError as exc:
            raise ConfigurationError(f"fault_monitor parameters: {exc}") from exc
        log_path = p("event_log").value
        try:
            self._log = EventLog(log_path or None)
        except (FaultMonitorError, OSError) as exc:
            raise ConfigurationError(f"parameter 'event_log' = {log_path!r}: {exc}") from exc
        self._rig_levels()
        self._trips = PlaneTrips(
            self._level(p("trip_displacement").value, "disp"),
            self._level(p("trip_1x").value, "1x"),
            p("trip_hysteresis").value,
            self._spr,
        )
        self._box = self._blackbox()
        self._monitor = FaultMonitor.from_rig(config, self._rig)
        self._meas_seq = SampleSequencer(self._spr)
        # coefficient messages every second sample: index // 2 is consecutive (module notes)
        self._coef_seq = SampleSequencer(self._spr // 2)
        self._omega = 0.0
        self.received = self.restarts = self.bags_written = 0
        self.events_published = 0  # this run's, not the log's (amb-run waits for the bag)
        self.control_transients = 0
        self._last_control: dict | None = None
        # indices of the last measurement and coefficient message processed: on /diagnostics,
        # so that amb-run stops the monitor only once it has caught up with the plant
        self.last_sample: int | None = None
        self._own_readers = bus is None  # composed, the stack's bus orders the two streams
        # coefficient messages held until the measurement of their last sample (its control
        # force) has been processed, two revolutions of messages at most: _deliver
        self._held = CoefficientHold(self._spr, HELD_TIMEOUT)
        self.last_coefficient_sample: int | None = None
        self.counts = dict.fromkeys(("measurements_rejected", "coefficients_rejected"), 0)
        self._last_reason = ""
        self._warnings = ThrottledWarnings(self.get_logger(), period=5.0)
        self.add_on_set_parameters_callback(self._on_set)
        self.add_post_set_parameters_callback(self._after_set)
        qos = stream_qos(self._spr)
        qos.depth = max(qos.depth, QUEUE_REVS * self._spr)  # not in the loop: may lag, not lose
        # composed: handed to the stack's own readers (controller, recorder) in process as well
        backlog = declare_catch_up(self)
        self._pub = stream_publisher(
            self,
            bus,
            FaultEventMsg,
            topics.FAULT_EVENTS,
            QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE),
            lossless=backlog.keeps_every_message,
        )
        self._diag = self.create_publisher(DiagnosticArray, topics.DIAGNOSTICS, 10)
        self._readers = (
            stream_subscription(
                self, bus, WaveletCoefficients, topics.COEFFICIENTS, self._on_coefficients, qos,
                backlog.per_message(topics.SAMPLES_PER_COEFFICIENT_MESSAGE),
            ),
            stream_subscription(
                self, bus, Measurement, topics.MEASUREMENT, self._on_measurement, qos, backlog
            ),
        )  # fmt: skip
        self._status_timer = self.create_timer(p("status_period").value, self._publish_status)
        # DDS readers (composed, the streams may come in process) move to a participant of
        # their own when the transport stops feeding them (amb_tools.reader_participant)
        self._deaf = watch_readers(self, self._readers[::-1] if bus is None else (), self._heard)
        self.get_logger().info(
            f"{len(self._log.events)} logged events reloaded; contacts per bearing "
            f"{dict(self._log.contacts)}"
        )

    # ------------------------------------------------------------------ configuration
    def _declare(self, name: str, default: object, desc: ParameterDescriptor) -> None:
        """Declare a parameter; an override rclpy refuses (range, type) is a ConfigurationError."""
        try:
            self.declare_parameter(name, default, desc)
        except (InvalidParameterValueException, InvalidParameterTypeException) as exc:
            ranges = [(r.from_value, r.to_value) for r in desc.floating_point_range] + [
                (r.from_value, r.to_value) for r in desc.integer_range
            ]
            allowed = f"{ranges[0][0]:g}..{ranges[0][1]:g}" if ranges else type(default).__name__
            raise ConfigurationError(
                f"parameter '{name}' refused ({exc.args[0]}): allowed {allowed} "
                f"({desc.description})"
            ) from exc

    def _levels(self, values: list[int]) -> tuple[int, ...]:
        """The configured detail levels (``[0]`` = all); each must exist in the stream."""
        try:
            deepest = revolution_level(self._spr) + EXTRA_OCTAVES + 1
        except ValueError as exc:
            raise ConfigurationError(f"parameter 'samples_per_rev' = {self._spr}: {exc}") from exc
        if values == [0]:
            return ()
        bad = [j for j in values if not 1 <= j <= deepest]
        if bad or not values:
            raise ConfigurationError(
                f"parameter 'levels' = {values}: expected [0] (all) or levels 1..{deepest} "
                f"(log2(samples_per_rev) + 2 with samples_per_rev = {self._spr}: the "
                "filterbank's deepest detail and its approximation)"
            )
        return tuple(values)

    def _rig_levels(self) -> None:
        """Load the rig file (``rig`` parameter): the monitor's rig and the default trip levels."""
        path = self.get_parameter("rig").value
        try:
            rig = load_rig(path or None)
        except (RigError, OSError, yaml.YAMLError) as exc:
            shown = path or "config/rig.yaml"
            raise ConfigurationError(f"parameter 'rig' = {shown!r}: {exc}") from exc
        try:
            self._clearance = clearance_levels(rig, 1.0)  # m, nearest clearance per plane
        except FaultMonitorError as exc:
            raise ConfigurationError(f"parameter 'rig' = {path!r}: {exc}") from exc
        self._rig = rig  # the monitor's rig fields: FaultMonitor.from_rig

    def _blackbox(self) -> BlackBox | None:
        p = self.get_parameter
        folder = p("blackbox_dir").value
        if not folder:
            return None
        try:
            box = BlackBox(folder, p("blackbox_pre_s").value, p("blackbox_post_s").value)
            box.folder.mkdir(parents=True, exist_ok=True)
        except (FaultMonitorError, OSError) as exc:
            raise ConfigurationError(f"parameter 'blackbox_dir' = {folder!r}: {exc}") from exc
        return box

    def destroy_node(self) -> None:
        """Write an open black-box capture, then close the readers' participant and the node."""
        if self._box is not None and self._box.flush() is not None:
            self.bags_written += 1
        super().destroy_node()

    def _heard(self) -> tuple[int | None, int, int]:
        """Changes whenever a measurement arrived (processed, rejected or sequenced away)."""
        rejected = self.counts["measurements_rejected"]
        return self.last_sample, rejected, sum(self._meas_seq.counts.values())

    def _level(self, value: float, which: str) -> float | np.ndarray:
        """Trip level per plane, m: ``value`` if > 0, else the fraction of the clearances."""
        if value > 0:
            return float(value)
        name = "trip_displacement_fraction" if which == "disp" else "trip_1x_fraction"
        return self.get_parameter(name).value * self._clearance

    # ------------------------------------------------------------------ run-time parameters
    def _on_set(self, params) -> SetParametersResult:
        """Check a run-time change as a whole; refuse it with the reason (old values kept)."""
        for prm in params:
            if prm.name not in RUNTIME:
                continue  # read-only ones never get here (rclpy refuses them, naming them)
            why = check_runtime_value(prm.name, prm.value)
            if why is not None:
                return SetParametersResult(successful=False, reason=why)
        return SetParametersResult(successful=True)

    def _after_set(self, params) -> None:
        """Apply an accepted change (the parameters already hold the new values)."""
        names = {prm.name for prm in params}
        p = self.get_parameter
        if names & {"trip_displacement", "trip_displacement_fraction"}:
            self._trips.displacement.set_level(self._level(p("trip_displacement").value, "disp"))
        if names & {"trip_1x", "trip_1x_fraction"}:
            self._trips.amplitude.set_level(self._level(p("trip_1x").value, "1x"))
        if "trip_hysteresis" in names:
            self._trips.set_hysteresis(p("trip_hysteresis").value)
        changed = {name: p(name).value for name in MONITOR_RUNTIME if name in names}
        if changed:
            self._monitor.config = replace(self._monitor.config, **changed)
        if "status_period" in names:
            self._status_timer.cancel()
            self._status_timer = self.create_timer(p("status_period").value, self._publish_status)

    # ------------------------------------------------------------------ streams
    def _record(
        self, topic: str, msgtype: str, msg: MeasurementView | CoefficientsView, raw: bytes
    ) -> None:
        """Hand an accepted message's CDR, as received, to the black box; write a completed bag."""
        if self._box is None:
            return
        t_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        path = self._box.add(self.resolve_topic_name(topic), msgtype, t_ns, raw)
        if path is not None:
            self.bags_written += 1
            self.get_logger().info(f"black box written to {path}")

    def _reject(self, counter: str, reason: str) -> None:
        self.counts[counter] += 1
        self._last_reason = reason
        self._warnings.warning(counter, reason)

    def _sequence(
        self,
        stream: str,
        seq: SampleSequencer,
        index: int,
        item: tuple,
        omega: float,
        reader: BacklogReader | None,
        restarted: bool = False,
    ) -> list:
        """Offer a checked (message view, CDR) pair to a stream's sequencer; return accepted pairs.

        ``stream`` names it for the warnings (throttled per stream); ``reader`` is the stream's
        DDS reader (a jump right after its drops is a known gap, :func:`gap_known`);
        ``restarted``: the message says its producer restarted its filters before it (a jump
        to it is the producer's own gap, known as well).
        """
        before = dict(seq.counts)
        accepted = seq.push(
            index, stamp_seconds(item[0].header.stamp), omega, item,
            restarted or gap_known(reader),
        )  # fmt: skip
        if seq.counts != before:
            self._last_reason = seq.last_reason
            if any(seq.counts[k] != before[k] for k in ("stray", "stamp", "repeat")):
                self._warnings.warning(f"sequence {stream}", self._last_reason)
        return accepted

    def _on_measurement(self, raw: bytes) -> None:
        try:
            msg = read_measurement(raw)
        except ValueError as exc:
            self._reject("measurements_rejected", f"measurement not readable: {exc}; dropped")
            return
        try:
            check_measurement(msg, self._spr)
        except MessageError as exc:
            self._reject("measurements_rejected", f"sample {msg.sample_index}: {exc}; dropped")
            return
        for reset, (m, r) in self._sequence(
            "measurements", self._meas_seq, int(msg.sample_index), (msg, raw),
            float(msg.rotor_speed), self._readers[1],
        ):  # fmt: skip
            if reset:
                self._trips.window.reset()  # the 1 x window must not straddle a discontinuity
            self._measurement(m, r)

    def _measurement(self, msg: MeasurementView, raw: bytes) -> None:
        self._record(topics.MEASUREMENT, "amb_msgs/msg/Measurement", msg, raw)
        self._omega = float(msg.rotor_speed)
        n = int(msg.sample_index)
        self._monitor.control_force(n, from_float_array(msg.wavelet_force))
        self.last_sample = n
        for ev in self._monitor.currents(
            n, from_float_array(msg.bearing_force), from_float_array(msg.current), self._omega
        ):
            self._emit(ev, msg.header.stamp, n)
        d = from_float_array(msg.displacement)
        self._monitor.displacements(n, d)
        for ev in self._trips.step(n, d, float(msg.rotor_angle), self._omega):
            self._emit(ev, msg.header.stamp, n)
        self._release(n)

    def _on_coefficients(self, raw: bytes) -> None:
        try:
            msg = read_coefficients(raw)
        except ValueError as exc:
            self._reject("coefficients_rejected", f"coefficients not readable: {exc}; dropped")
            return
        try:
            check_coefficients(msg, self._spr)
        except MessageError as exc:
            self._reject(
                "coefficients_rejected",
                f"coefficients of sample {msg.sample_index}: {exc}; dropped",
            )
            return
        n = int(msg.sample_index)
        if self._own_readers and (self.last_sample is None or n > self.last_sample):
            # each reader takes its whole queue at a wake (amb_tools.backlog): the measurements
            # up to this sample may wait behind this wake, and a sample's control force should
            # come before the coefficients it completes (FaultMonitor.control_force)
            self._readers[1].poll()
        omega = self._omega if self._omega > 0 else UNKNOWN_OMEGA
        index = n // 2
        last = self._coef_seq.last_index
        for reset, (m, r) in self._sequence(
            "coefficients", self._coef_seq, index, (msg, raw), omega, self._readers[0],
            last is not None and index > last + 1 and filterbank_restarted(msg),
        ):  # fmt: skip
            self._deliver(m, r, reset)

    def _deliver(self, msg: CoefficientsView, raw: bytes, reset: bool) -> None:
        """
        Process one sequenced coefficient message, or hold it until its samples are measured.

        Held (:mod:`amb_fault_monitor.coefficient_hold`) while its last sample's measurement
        has not been processed; the messages given back unmatched are counted
        (``coefficients_unmatched`` on /diagnostics) and logged.
        """
        if self._own_readers and self._held.wants(int(msg.sample_index), self.last_sample):
            over = self._held.hold((msg, raw, reset), time.monotonic())
            self._unmatched(over, "two revolutions of messages")
            return
        self._coefficients(msg, raw, reset)

    def _release(self, last_sample: int) -> None:
        """Process the held coefficient messages whose samples have all been measured."""
        if self._held:
            for item in self._held.release(last_sample, time.monotonic()):
                self._coefficients(*item)

    def _unmatched(self, items: list, why: str) -> None:
        """Process coefficient messages given back without their measurements."""
        if not items:
            return
        for item in items:
            self._coefficients(*item)
        self._warnings.warning(
            "unmatched",
            f"{len(items)} coefficient message(s) from sample {int(items[0][0].sample_index)} "
            f"processed without their measurements (held {why}): a control force kink in them "
            "is unknown",
        )

    def _coefficients(self, msg: CoefficientsView, raw: bytes, reset: bool) -> None:
        if reset and self._monitor.samples:
            self._restart(f"coefficient stream discontinuous at sample {msg.sample_index}")
        self._record(topics.COEFFICIENTS, "amb_msgs/msg/WaveletCoefficients", msg, raw)
        self.received += 1
        counted = self._monitor.control_transients
        self.last_coefficient_sample = int(msg.sample_index)
        try:
            events = self._monitor.step(record_from_msg(msg, self._omega))
        except RecordError as exc:  # not expected after the checks above: the last line
            self._restart(str(exc))
            return
        if self._monitor.control_transients != counted:
            self._control_transient(self._monitor.last_control_transient)
        for ev in events:
            self._emit(ev, msg.header.stamp, int(msg.sample_index))

    def _control_transient(self, info: dict) -> None:
        """Report a transient the monitor attributed to a control step (no event)."""
        self.control_transients += 1
        self._last_control = info
        self._last_reason = (
            f"transient from control action: onset at sample {info['onset_sample_index']}, "
            f"after a {info['step_n']:.3g} N step of the wavelet force from sample "
            f"{info['step_first_sample_index']}; not reported as "
            f"{info['classified_as']}"
        )
        self._warnings.warning("control transient", self._last_reason)

    def _restart(self, why: str) -> None:
        """Reset the monitor (it calibrates again) and report why."""
        self.restarts += 1
        self._last_reason = f"{why}: monitor reset, calibrating again"
        self._warnings.warning("restart", self._last_reason)
        self._monitor.reset()

    def _back_date(self, now: Time, now_index: int, index: int) -> Time:
        fs = self._spr * self._omega / (2 * math.pi)
        if fs <= 0:
            return now
        return stamp(max(stamp_seconds(now) - (now_index - index) / fs, 0.0))

    def _emit(self, ev: FaultEvent, stamp_in: StampView, now_index: int) -> None:
        now = Time(sec=stamp_in.sec, nanosec=stamp_in.nanosec)
        self._log.append(ev, stamp_seconds(now))
        if self._box is not None:
            t_ns = now.sec * 1_000_000_000 + now.nanosec
            self._box.trigger(t_ns, f"event_{ev.event_id:05d}_{ev.fault_type.name}")
        out = FaultEventMsg(
            event_id=ev.event_id,
            fault_type=int(ev.fault_type),
            onset_stamp=self._back_date(now, now_index, ev.onset_sample_index),
            detection_stamp=self._back_date(now, now_index, ev.detection_sample_index),
            onset_sample_index=max(int(ev.onset_sample_index), 0),
            detection_sample_index=int(ev.detection_sample_index),
            plane=int(ev.plane),
            channel=int(ev.channel),
            bearing=int(ev.bearing),
            severity=float(ev.severity),
            confidence=float(ev.confidence),
            count=int(ev.count),
            rotor_speed=float(ev.omega),
            evidence=[KeyValue(key=str(k), value=str(v)) for k, v in ev.evidence.items()],
            description=ev.description,
        )
        out.header.stamp = now
        out.header.frame_id = "rotor"
        self._pub.publish(serialize_message(out))
        self.events_published += 1
        self.get_logger().warning(f"{ev.fault_type.name}: {ev.description}")

    def _publish_status(self) -> None:
        self._unmatched(
            self._held.expired(time.monotonic()), f"{self._held.timeout:g} s without a measurement"
        )
        statuses = []
        disp, amp = self._trips.displacement, self._trips.amplitude
        for p in range(4):
            level = DiagnosticStatus.OK
            message = "ok"
            if disp.tripped[p]:
                level, message = DiagnosticStatus.ERROR, "displacement over the trip level"
            elif amp.tripped[p]:
                level, message = DiagnosticStatus.ERROR, "1 x amplitude over the trip level"
            elif self._monitor.alarm:
                level, message = DiagnosticStatus.WARN, "fault episode in progress"
            statuses.append(
                DiagnosticStatus(
                    level=level,
                    name=topics.diagnostic_name(
                        f"fault_monitor: plane {p + 1}", self.get_namespace()
                    ),
                    message=message,
                    values=[
                        KeyValue(key="peak_displacement_m", value=f"{disp.peak[p]:.6g}"),
                        KeyValue(key="trip_level_m", value=f"{disp.level[p]:.6g}"),
                        KeyValue(key="amplitude_1x_m", value=f"{amp.value[p]:.6g}"),
                        KeyValue(key="trip_1x_level_m", value=f"{amp.level[p]:.6g}"),
                    ],
                )
            )
        values = {
            "calibrated": self._monitor.calibrated,
            "recalibrations": self._monitor.recalibrations,
            "messages": self.received,
            "last_sample": self.last_sample,
            "last_coefficient_sample": self.last_coefficient_sample,
            "events_logged": len(self._log.events),
            "events_published": self.events_published,
            "restarts": self.restarts,
            "readers_renewed": self._deaf.renewals,
            "blackbox_bags": self.bags_written,
            "masked_channels": self._monitor.masked_channels,
            "control_transients": self.control_transients,
            "control_step_n": self._monitor.config.control_step,
            "last_control_transient": self._last_control or "",
            "coil_explained": self._monitor.coil_explained,
            "coefficients_unmatched": self._held.unmatched,
            **{f"contacts_bearing_{b}": c for b, c in sorted(self._log.contacts.items())},
            **self.counts,
            **{f"samples_{k}": v for k, v in self._meas_seq.counts.items()},
            **{f"coefficients_{k}": v for k, v in self._coef_seq.counts.items()},
            "callback_errors": getattr(self, "callback_errors", 0),
            **matched_subscribers(self._pub),
            **backlog_counts(*self._readers),
        }
        problems = (
            any(self.counts.values())
            or self.control_transients
            or any(seq.counts[k] for seq in (self._meas_seq, self._coef_seq) for k in REFUSED)
        )
        ok = self._monitor.calibrated and not problems
        statuses.append(
            DiagnosticStatus(
                level=DiagnosticStatus.OK if ok else DiagnosticStatus.WARN,
                name=topics.diagnostic_name("fault_monitor", self.get_namespace()),
                message=self._last_reason
                or ("monitoring" if self._monitor.calibrated else "calibrating"),
                values=[KeyValue(key=k, value=str(v)) for k, v in values.items()],
            )
        )
        array = DiagnosticArray(status=statuses)
        array.header.stamp = self.get_clock().now().to_msg()
        self._diag.publish(array)


def main(args: list[str] | None = None) -> int:
    """Entry point of the ``fault_monitor`` executable."""
    return run_node(FaultMonitorNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
