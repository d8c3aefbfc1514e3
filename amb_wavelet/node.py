"""``wavelet_filterbank``: the measurement stream in, wavelet coefficients out (thesis ch. 4).

A thin ROS layer over :class:`amb_wavelet.frontend.ChannelFrontEnd` (fixed and synchronously
rotating frames, eq. 2.26; even/odd quadrature channels, section 4.3) and
:class:`amb_wavelet.analysis.AnalysisFilterbank` (causal polyphase filterbank, fig. 4.3,
eq. 4.12-4.28). Each ``Measurement`` is pushed through both; every coefficient that sample
completes is published at once, all of them in one ``WaveletCoefficients`` message with one
``CoefficientSet`` per (level, kind, frame, quadrature). Both streams are handled as CDR bytes
(:mod:`amb_tools.cdr`: the measurement subscribed ``raw``, the coefficients serialised without
building rclpy message objects), the cost that dominated this node at 67 Hz x 32 samples/rev.

Every measurement is validated first (:func:`amb_tools.validation.check_measurement`: array
lengths, finite values, ``rotor_speed`` > 0, ``rotor_angle`` in [0, 2 pi), the configured
``samples_per_rev``) and then sequenced (:class:`amb_tools.validation.SampleSequencer`):
a repeated index is dropped; a stamp that goes back or lies impossibly far ahead of the
sample interval is rejected; a jump or a step back is held until the next sample confirms
it, except a jump right after the samples this node's reader dropped to catch up (a known
gap, accepted at once: the stream may end there). A confirmed gap or restart (a lost sample,
a restarted plant) resets the filterbank at the new index, so no coefficient ever mixes
samples from both sides of a discontinuity (start-up coefficients after a reset are flagged
``settled = false``); an unconfirmed one is a stray message and is dropped. Everything
rejected is counted by reason and reported on ``/diagnostics``; nothing rejected reaches the
filterbank.

Structural parameters are read-only (they fix the filterbank); only ``status_period`` may be
set at run time (it is validated by the on-set callback and applied to the report timer).
"""

from __future__ import annotations

import math

import numpy as np
from amb_msgs.msg import Measurement, WaveletCoefficients
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import (
    SetParametersResult,
)
from rclpy.node import Node

from amb_common import topics
from amb_tools.backlog import backlog_counts, declare_catch_up, gap_known
from amb_tools.cdr import MeasurementView, read_measurement
from amb_tools.conversions import MessageError, stamp_seconds
from amb_tools.local_bus import LocalBus, stream_publisher, stream_subscription
from amb_tools.node_main import ConfigurationError, descriptor, run_node
from amb_tools.reader_participant import ClosesReaderParticipant, watch_readers
from amb_tools.streams import FRAME_CODES, QUAD_CODES, matched_subscribers, stream_qos
from amb_tools.throttled_log import ThrottledWarnings
from amb_tools.validation import SampleSequencer, check_measurement
from amb_wavelet.analysis import AnalysisFilterbank
from amb_wavelet.errors import LevelError, WaveletNameError
from amb_wavelet.filters import get_filters
from amb_wavelet.frontend import FRAMES, QUADRATURES, ChannelFrontEnd
from amb_wavelet.levels import check_level, revolution_level
from amb_wavelet.messages import coefficients_bytes


class WaveletFilterbankNode(ClosesReaderParticipant, Node):
    """Publish the wavelet coefficients of the measurement stream (module docstring)."""

    def __init__(self, bus: LocalBus | None = None) -> None:
        super().__init__("wavelet_filterbank")
        d = self.declare_parameter
        d("wavelet", "haar", descriptor("PyWavelets name (orthogonal)"))
        d("samples_per_rev", 64, descriptor("samples per revolution, power of two", ints=(4, 4096)))
        d(
            "samples_per_period",
            0,
            descriptor("control period in samples (0 = samples_per_rev)", ints=(0, 65536)),
        )
        d(
            "levels",
            0,
            descriptor(
                "filterbank levels J (0 = log2(samples_per_rev) + 1: down to 0.5 x)", ints=(0, 16)
            ),
        )
        d("frames", list(FRAMES), descriptor("fixed, rotating"))
        d("quadrature", list(QUADRATURES), descriptor("even, odd"))
        d(
            "quarter_delay",
            0,
            descriptor("odd-channel delay in samples (0 = samples_per_rev / 4)", ints=(0, 65536)),
        )
        d(
            "status_period",
            1.0,
            descriptor(
                "period of the /diagnostics report, s (wall clock)",
                read_only=False,
                floats=(0.05, 60.0),
            ),
        )
        self._configure()
        qos = stream_qos(self._samples_per_period)
        catch_up = declare_catch_up(self)
        self._pub = stream_publisher(
            self, bus, WaveletCoefficients, topics.COEFFICIENTS, qos,
            lossless=catch_up.keeps_every_message,
        )  # fmt: skip
        self._diag = self.create_publisher(DiagnosticArray, topics.DIAGNOSTICS, 10)
        self._meas_reader = stream_subscription(
            self, bus, Measurement, topics.MEASUREMENT, self._on_measurement, qos,
            catch_up, urgent=True,  # the controller waits for the coefficients
        )  # fmt: skip
        self._status_timer = self.create_timer(
            self.get_parameter("status_period").value, self._publish_status
        )
        self.samples = self.published = self.rejected = 0
        self.last_sample: int | None = None  # index of the last sample processed (amb-run drains)
        self._last_reason = ""
        self._warnings = ThrottledWarnings(self.get_logger(), period=5.0)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        # the measurements' DDS reader moves to a participant of its own when the transport
        # stops feeding it (amb_tools.reader_participant); composed, it is the reader the stack
        # shares, held by this node (the first composed), and every composed reader follows
        self._deaf = watch_readers(self, [self._meas_reader], self._heard)
        self.get_logger().info(
            f"{self._wavelet}, {self._levels} levels, frames {self._frames}, "
            f"quadrature {self._quad}, {self._spr} samples/rev"
        )

    def _configure(self) -> None:
        p = self.get_parameter
        self._wavelet = p("wavelet").value
        self._spr = p("samples_per_rev").value
        spp = p("samples_per_period").value
        self._samples_per_period = spp or self._spr
        self._frames = tuple(p("frames").value)
        self._quad = tuple(p("quadrature").value)
        try:
            rev = revolution_level(self._spr)
        except LevelError as exc:
            raise ConfigurationError(f"parameter 'samples_per_rev' = {self._spr}: {exc}") from exc
        levels = p("levels").value or rev + 1
        try:
            get_filters(self._wavelet)
        except WaveletNameError as exc:
            raise ConfigurationError(f"parameter 'wavelet' = {self._wavelet!r}: {exc}") from exc
        try:
            self._levels = check_level(levels, self._spr)
        except LevelError as exc:
            raise ConfigurationError(
                f"parameter 'levels' = {levels}: {exc} (samples_per_rev = {self._spr})"
            ) from exc
        try:
            self._front = ChannelFrontEnd(
                self._spr, self._frames, self._quad, quarter_delay=p("quarter_delay").value or None
            )
        except ValueError as exc:
            raise ConfigurationError(f"parameters 'frames'/'quadrature': {exc}") from exc
        self._frames = tuple(f for f in FRAMES if f in self._frames)  # the front end's order
        self._quad = tuple(q for q in QUADRATURES if q in self._quad)
        self._bank = AnalysisFilterbank(self._wavelet, self._levels, self._front.n_channels)
        self._slots = [(FRAME_CODES[f], QUAD_CODES[q]) for f in self._frames for q in self._quad]
        self._sequencer = SampleSequencer(self._spr)

    def _on_set_parameters(self, params) -> SetParametersResult:
        """Run-time changes: only ``status_period`` (read-only ones are refused by rclpy)."""
        for param in params:
            if param.name == "status_period":
                value = param.value
                if not (isinstance(value, float) and math.isfinite(value) and 0.05 <= value):
                    return SetParametersResult(
                        successful=False,
                        reason=f"parameter 'status_period' = {value!r}: expected 0.05..60.0 s",
                    )
        for param in params:
            if param.name == "status_period":
                self._status_timer.cancel()
                self._status_timer = self.create_timer(param.value, self._publish_status)
        return SetParametersResult(successful=True)

    @property
    def gaps(self) -> int:
        """Confirmed discontinuities (gaps and restarts) that reset the filterbank."""
        return self._sequencer.counts["gap"] + self._sequencer.counts["restart"]

    @property
    def repeats(self) -> int:
        """Repeated sample indices dropped."""
        return self._sequencer.counts["repeat"]

    def _reject(self, reason: str) -> None:
        self.rejected += 1
        self._last_reason = reason
        self._warnings.warning("rejected", reason)

    def _heard(self) -> tuple[int, int, int]:
        """Changes whenever a measurement arrived (processed, rejected or sequenced away)."""
        return self.samples, self.rejected, sum(self._sequencer.counts.values())

    def _on_measurement(self, raw: bytes) -> None:
        try:
            msg = read_measurement(raw)
        except ValueError as exc:
            self._reject(f"measurement of {len(raw)} bytes unreadable: {exc}; dropped")
            return
        try:
            check_measurement(msg, self._spr)
        except MessageError as exc:
            self._reject(f"sample {msg.sample_index}: {exc}; dropped")
            return
        before = dict(self._sequencer.counts)
        accepted = self._sequencer.push(
            int(msg.sample_index), stamp_seconds(msg.header.stamp), msg.rotor_speed, msg,
            gap_known(self._meas_reader),
        )  # fmt: skip
        if self._sequencer.counts != before:
            self._last_reason = self._sequencer.last_reason
            if any(self._sequencer.counts[k] != before[k] for k in ("stray", "stamp")):
                self._warnings.warning("sequence", self._last_reason)
        for reset, m in accepted:
            self._step(m, reset)

    def _step(self, msg: MeasurementView, reset: bool) -> None:
        index = int(msg.sample_index)
        xy = msg.displacement
        if reset:
            self._front.reset()
            self._bank.reset(start_sample_index=index)
        self.samples += 1
        self.last_sample = index
        coefficients = self._bank.step(self._front.step(xy, msg.rotor_angle), index)
        if not coefficients:
            return
        if not all(np.all(np.isfinite(c.values)) for c in coefficients):
            # cannot happen for bounded, finite inputs; never publish it, restart the filters
            self._reject(f"sample {index}: non-finite coefficient computed; filterbank reset")
            self._sequencer.reset()
            return
        out = coefficients_bytes(
            msg.header,
            self._wavelet,
            self._spr,
            self._samples_per_period,
            index,
            msg.rotor_speed,
            coefficients,
            self._slots,
        )
        self._pub.publish(out)
        self.published += 1

    def _publish_status(self) -> None:
        level = DiagnosticStatus.OK
        counts = self._sequencer.counts
        if self.rejected or self.gaps or counts["stray"] or counts["stamp"]:
            level = DiagnosticStatus.WARN
        values = {
            "samples": self.samples,
            "last_sample": self.last_sample,
            "messages_published": self.published,
            "gaps_reset": self.gaps,
            "repeats_dropped": self.repeats,
            "rejected": self.rejected,
            "stray_dropped": counts["stray"],
            "stamp_rejected": counts["stamp"],
            "restarts": counts["restart"],
            "readers_renewed": self._deaf.renewals,
            "callback_errors": getattr(self, "callback_errors", 0),
            "wavelet": self._wavelet,
            "levels": self._levels,
            **matched_subscribers(self._pub),
            **backlog_counts(self._meas_reader),
        }
        status = DiagnosticStatus(
            level=level,
            name=topics.diagnostic_name("wavelet_filterbank", self.get_namespace()),
            message=self._last_reason or "ok",
            values=[KeyValue(key=k, value=str(v)) for k, v in values.items()],
        )
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self._diag.publish(array)


def main(args: list[str] | None = None) -> int:
    """Entry point of the ``wavelet_filterbank`` executable."""
    return run_node(WaveletFilterbankNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
