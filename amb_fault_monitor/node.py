"""``fault_monitor``: wavelet coefficients in, fault events and diagnostics out (thesis ch. 5).

A thin ROS layer over :class:`amb_fault_monitor.monitor.FaultMonitor`. Each
``WaveletCoefficients`` message becomes one
:class:`~amb_fault_monitor.records.SampleCoefficients`; the events the core decides are
numbered and written to the JSON-lines event log (``event_log`` parameter, reloaded at start
with its contact counters) and published as ``amb_msgs/FaultEvent`` on ``/amb/fault/events``.
``Measurement`` messages feed two trips per plane with hysteresis
(:mod:`amb_fault_monitor.trips`): the radial displacement and the 1 x orbit semi-major axis
over the last revolution. Their levels default to fractions (``trip_displacement_fraction``,
``trip_1x_fraction``) of the clearance of the nearest clearance bearing read from the rig file
(``rig`` parameter, default ``config/rig.yaml``); ``trip_displacement`` / ``trip_1x`` > 0
override them in m. A trip is an ERROR on ``/diagnostics`` and a ``TRIP`` event.
``/diagnostics`` carries one status per sensor plane (OK / WARN while an episode is open /
ERROR when tripped) and one for the monitor.

Black box (``blackbox_dir`` non-empty): every received measurement and coefficient message is
serialised (``rclpy.serialization.serialize_message``) into a ring buffer of
``blackbox_pre_s`` seconds; at each event ``blackbox_post_s`` more seconds are captured and the
lot written to its own bag ``blackbox_dir/event_<id>_<TYPE>`` (topic names as subscribed).

Stamps: the coefficient message carries the stamp of its completing sample; the onset and
detection stamps are back-dated from it by ``(sample_index - n) / fs`` at the current speed.
"""

from __future__ import annotations

import math

from amb_msgs.msg import CoefficientSet as CoefficientSetMsg
from amb_msgs.msg import FaultEvent as FaultEventMsg
from amb_msgs.msg import Measurement, WaveletCoefficients
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message

from amb_fault_monitor.blackbox import BlackBox
from amb_fault_monitor.errors import FaultMonitorError, RecordError
from amb_fault_monitor.event_log import EventLog
from amb_fault_monitor.events import FaultEvent, FaultType
from amb_fault_monitor.monitor import FaultMonitor, MonitorConfig
from amb_fault_monitor.records import CoefficientSet, SampleCoefficients
from amb_fault_monitor.trips import SynchronousAmplitude, TripMonitor, clearance_levels
from amb_tools.conversions import from_float_array, stamp, stamp_seconds
from amb_tools.node_main import ConfigurationError, run_node
from amb_wavelet.node import stream_qos

KIND = {CoefficientSetMsg.KIND_DETAIL: "detail", CoefficientSetMsg.KIND_APPROXIMATION: "approx"}
FRAME = {CoefficientSetMsg.FRAME_FIXED: "fixed", CoefficientSetMsg.FRAME_ROTATING: "rotating"}
QUAD = {CoefficientSetMsg.QUADRATURE_EVEN: "even", CoefficientSetMsg.QUADRATURE_ODD: "odd"}


def record_from_msg(msg: WaveletCoefficients, omega: float) -> SampleCoefficients:
    """Convert a ``WaveletCoefficients`` message into the core's record."""
    sets = tuple(
        CoefficientSet(
            int(s.level),
            "detail" if s.kind == CoefficientSetMsg.KIND_DETAIL else "approximation",
            FRAME[s.frame],
            QUAD[s.quadrature],
            int(s.translation_index),
            int(s.first_sample_index),
            int(s.last_sample_index),
            from_float_array(s.values),
            bool(s.settled),
        )
        for s in msg.sets
    )
    return SampleCoefficients(int(msg.sample_index), float(omega), sets)


class FaultMonitorNode(Node):
    """Publish fault events classified from the wavelet coefficients (module docstring)."""

    def __init__(self) -> None:
        super().__init__("fault_monitor")
        ro = {"read_only": True}

        def dbl(name, value, desc, lo, hi, **kw):
            rng = [FloatingPointRange(from_value=lo, to_value=hi)]
            self.declare_parameter(
                name, value, ParameterDescriptor(description=desc, floating_point_range=rng, **kw)
            )

        self.declare_parameter(
            "samples_per_rev",
            32,
            ParameterDescriptor(
                description="samples per revolution of the coefficient stream, power of two",
                integer_range=[IntegerRange(from_value=4, to_value=4096)],
                **ro,
            ),
        )
        self.declare_parameter(
            "levels",
            [0],
            ParameterDescriptor(description="detail levels used ([0] = all received)", **ro),
        )
        self.declare_parameter(
            "frames",
            ["fixed", "rotating"],
            ParameterDescriptor(description="fixed, rotating", **ro),
        )
        dbl("calibration_revs", 16.0, "healthy calibration window, revolutions", 1.0, 1e4, **ro)
        dbl("k", 8.0, "robust standard deviations of the thresholds", 1.0, 100.0, **ro)
        dbl("threshold_floor", 2.0e-8, "smallest threshold, m", 0.0, 1e-3, **ro)
        dbl(
            "decision_revs",
            16.0,
            "longest wait from alarm to decision, revolutions",
            0.5,
            1e3,
            **ro,
        )
        dbl(
            "decision_max_revs", 32.0,
            "longest wait while the 1 x level still moves far from its reference, revolutions "
            "(>= decision_revs)", 0.5, 1e3, **ro,
        )  # fmt: skip
        dbl("quiet_revs", 2.0, "hold-off: quiet revolutions that end an episode", 0.25, 1e3, **ro)
        self.declare_parameter(
            "event_log",
            "",
            ParameterDescriptor(description="JSON-lines event log path ('' = off)", **ro),
        )
        self.declare_parameter(
            "rig",
            "",
            ParameterDescriptor(
                description="rig file for the clearances ('' = config/rig.yaml)", **ro
            ),
        )
        dbl(
            "trip_displacement", 0.0, "radial trip level, m (0 = from the rig clearances)", 0.0, 0.1
        )
        dbl(
            "trip_displacement_fraction", 2.0 / 3.0,
            "default radial trip level as a share of the nearest clearance", 0.01, 1.0,
        )  # fmt: skip
        dbl("trip_1x", 0.0, "1 x orbit semi-major axis trip level, m (0 = from the rig)", 0.0, 0.1)
        dbl(
            "trip_1x_fraction", 0.5,
            "default 1 x trip level as a share of the nearest clearance", 0.01, 1.0,
        )  # fmt: skip
        dbl("trip_hysteresis", 0.1, "trip clears below level * (1 - this)", 0.0, 0.99)
        dbl("status_period", 1.0, "period of the /diagnostics report, s (wall clock)", 0.05, 60.0)
        self.declare_parameter(
            "blackbox_dir",
            "",
            ParameterDescriptor(
                description="folder of the per-event black-box bags ('' = off)", **ro
            ),
        )
        dbl("blackbox_pre_s", 2.0, "black box: seconds kept before an event", 0.0, 600.0, **ro)
        dbl("blackbox_post_s", 1.0, "black box: seconds recorded after an event", 0.0, 600.0, **ro)
        p = self.get_parameter
        levels = tuple(int(j) for j in p("levels").value if int(j) > 0)
        self._spr = p("samples_per_rev").value
        try:
            config = MonitorConfig(
                self._spr,
                levels=levels,
                frames=tuple(p("frames").value),
                calibration_revs=p("calibration_revs").value,
                k=p("k").value,
                threshold_floor=p("threshold_floor").value,
                decision_revs=p("decision_revs").value,
                quiet_revs=p("quiet_revs").value,
                decision_max_revs=p("decision_max_revs").value,
            )
            self._log = EventLog(p("event_log").value or None)
            from amb_plant_sim.rig import load_rig

            rig = load_rig(p("rig").value or None)
            self._default_disp = clearance_levels(rig, p("trip_displacement_fraction").value)
            self._default_1x = clearance_levels(rig, p("trip_1x_fraction").value)
            hyst = p("trip_hysteresis").value
            self._trip = TripMonitor(self._level(p("trip_displacement").value, "disp"), hyst)
            self._trip_1x = TripMonitor(self._level(p("trip_1x").value, "1x"), hyst)
            self._sync_amp = SynchronousAmplitude(self._spr)
            folder = p("blackbox_dir").value
            self._box = (
                BlackBox(folder, p("blackbox_pre_s").value, p("blackbox_post_s").value)
                if folder
                else None
            )
        except (FaultMonitorError, OSError) as exc:
            raise ConfigurationError(f"fault_monitor parameters: {exc}") from exc
        self._monitor = FaultMonitor(config)
        self.add_on_set_parameters_callback(self._on_set)
        qos = stream_qos(self._spr)
        self._pub = self.create_publisher(
            FaultEventMsg,
            "/amb/fault/events",
            QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE),
        )
        self._diag = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._coef_sub = self.create_subscription(
            WaveletCoefficients, "/amb/wavelet/coefficients", self._on_coefficients, qos
        )
        self._meas_sub = self.create_subscription(
            Measurement, "/amb/measurement", self._on_measurement, qos
        )
        self.create_timer(p("status_period").value, self._publish_status)
        self._omega = 0.0
        self.received = self.rejected = self.restarts = self.bags_written = 0
        self._last_reason = ""
        self.get_logger().info(
            f"{len(self._log.events)} logged events reloaded; contacts per bearing "
            f"{dict(self._log.contacts)}"
        )

    def destroy_node(self) -> None:
        """Write an open black-box capture before the node goes away."""
        if self._box is not None and self._box.flush() is not None:
            self.bags_written += 1
        super().destroy_node()

    def _level(self, value: float, which: str):
        """Trip level per plane, m: ``value`` if > 0, else the clearance-derived default."""
        if value > 0:
            return float(value)
        return (self._default_disp if which == "disp" else self._default_1x).copy()

    def _on_set(self, params):
        from rcl_interfaces.msg import SetParametersResult

        for prm in params:
            if prm.name in ("trip_displacement", "trip_1x") and not prm.value >= 0:
                return SetParametersResult(successful=False, reason=f"{prm.name} >= 0 m")
        for prm in params:
            if prm.name == "trip_displacement":
                self._trip.set_level(self._level(float(prm.value), "disp"))
            elif prm.name == "trip_1x":
                self._trip_1x.set_level(self._level(float(prm.value), "1x"))
            elif prm.name == "trip_hysteresis":
                self._trip.hysteresis = self._trip_1x.hysteresis = float(prm.value)
        return SetParametersResult(successful=True)

    def _record(self, sub, msgtype: str, msg) -> None:
        """Hand a received message to the black box; write its bag when a capture completes."""
        if self._box is None:
            return
        t_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        path = self._box.add(sub.topic_name, msgtype, t_ns, serialize_message(msg))
        if path is not None:
            self.bags_written += 1
            self.get_logger().info(f"black box written to {path}")

    def _on_measurement(self, msg: Measurement) -> None:
        self._record(self._meas_sub, "amb_msgs/msg/Measurement", msg)
        self._omega = float(msg.rotor_speed)
        n = int(msg.sample_index)
        d = msg.displacement
        amp = self._sync_amp.step(d, float(msg.rotor_angle))
        found = [("displacement", pl, self._trip) for pl in self._trip.step(d)]
        if self._sync_amp.ready:
            found += [("1x", pl, self._trip_1x) for pl in self._trip_1x.update(amp)[0]]
        for kind, plane, trip in found:
            r = float(trip.value[plane])
            level = float(trip.level[plane])
            what = "displacement" if kind == "displacement" else "1 x amplitude"
            ev = FaultEvent(
                FaultType.TRIP, n, n, n, self._spr, self._omega,
                plane=int(plane) + 1,
                severity=r,
                confidence=1.0,
                evidence={"quantity": kind, "trip_level_m": level, "value_m": r},
                description=f"plane {plane + 1} {what} {r:.3g} m over the trip level {level:.3g} m",
            )  # fmt: skip
            self._emit(ev, msg.header.stamp, n)

    def _on_coefficients(self, msg: WaveletCoefficients) -> None:
        self._record(self._coef_sub, "amb_msgs/msg/WaveletCoefficients", msg)
        self.received += 1
        omega = self._omega or 0.0
        try:
            events = self._monitor.step(record_from_msg(msg, omega))
        except RecordError as exc:
            self.restarts += 1
            self._last_reason = f"{exc}: monitor reset, calibrating again"
            self.get_logger().warning(self._last_reason, throttle_duration_sec=5.0)
            self._monitor.reset()
            return
        for ev in events:
            self._emit(ev, msg.header.stamp, int(msg.sample_index))

    def _back_date(self, now: Time, now_index: int, index: int) -> Time:
        fs = self._spr * self._omega / (2 * math.pi)
        if fs <= 0:
            return now
        return stamp(max(stamp_seconds(now) - (now_index - index) / fs, 0.0))

    def _emit(self, ev: FaultEvent, now: Time, now_index: int) -> None:
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
        self._pub.publish(out)
        self.get_logger().warning(f"{ev.fault_type.name}: {ev.description}")

    def _publish_status(self) -> None:
        statuses = []
        for p in range(4):
            level = DiagnosticStatus.OK
            message = "ok"
            if self._trip.tripped[p]:
                level, message = DiagnosticStatus.ERROR, "displacement over the trip level"
            elif self._trip_1x.tripped[p]:
                level, message = DiagnosticStatus.ERROR, "1 x amplitude over the trip level"
            elif self._monitor.alarm:
                level, message = DiagnosticStatus.WARN, "fault episode in progress"
            statuses.append(
                DiagnosticStatus(
                    level=level,
                    name=f"fault_monitor: plane {p + 1}",
                    message=message,
                    values=[
                        KeyValue(key="peak_displacement_m", value=f"{self._trip.peak[p]:.6g}"),
                        KeyValue(key="trip_level_m", value=f"{self._trip.level[p]:.6g}"),
                        KeyValue(key="amplitude_1x_m", value=f"{self._trip_1x.value[p]:.6g}"),
                        KeyValue(key="trip_1x_level_m", value=f"{self._trip_1x.level[p]:.6g}"),
                    ],
                )
            )
        values = {
            "calibrated": self._monitor.calibrated,
            "messages": self.received,
            "events_logged": len(self._log.events),
            "restarts": self.restarts,
            "blackbox_bags": self.bags_written,
            "masked_channels": self._monitor.masked_channels,
            **{f"contacts_bearing_{b}": c for b, c in sorted(self._log.contacts.items())},
        }
        statuses.append(
            DiagnosticStatus(
                level=DiagnosticStatus.OK if self._monitor.calibrated else DiagnosticStatus.WARN,
                name="fault_monitor",
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
