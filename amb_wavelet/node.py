"""``wavelet_filterbank``: the measurement stream in, wavelet coefficients out (thesis ch. 4).

A thin ROS layer over :class:`amb_wavelet.frontend.ChannelFrontEnd` (fixed and synchronously
rotating frames, eq. 2.26; even/odd quadrature channels, section 4.3) and
:class:`amb_wavelet.analysis.AnalysisFilterbank` (causal polyphase filterbank, fig. 4.3,
eq. 4.12-4.28). Each ``Measurement`` is pushed through both; every coefficient that sample
completes is published at once, all of them in one ``WaveletCoefficients`` message with one
``CoefficientSet`` per (level, kind, frame, quadrature).

Sample indices must arrive consecutively. A repeated index is dropped; a gap or a step back
(a lost sample, a restarted plant) resets the filterbank at the new index, so no coefficient
ever mixes samples from both sides of a discontinuity (start-up coefficients after a reset are
flagged ``settled = false``). A measurement with a non-finite displacement, angle or speed is
rejected. All three are counted and reported on ``/diagnostics``.

Parameters are read-only (they fix the structure of the filterbank); see ``declare``.
"""

from __future__ import annotations

import math

import numpy as np
from amb_msgs.msg import CoefficientSet, Measurement, WaveletCoefficients
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from amb_tools.conversions import coefficients_msg
from amb_tools.node_main import ConfigurationError, run_node
from amb_wavelet.analysis import AnalysisFilterbank
from amb_wavelet.errors import LevelError, WaveletNameError
from amb_wavelet.filters import get_filters
from amb_wavelet.frontend import FRAMES, QUADRATURES, ChannelFrontEnd
from amb_wavelet.levels import check_level, revolution_level

FRAME_CODES = {"fixed": CoefficientSet.FRAME_FIXED, "rotating": CoefficientSet.FRAME_ROTATING}
QUAD_CODES = {"even": CoefficientSet.QUADRATURE_EVEN, "odd": CoefficientSet.QUADRATURE_ODD}


def stream_qos(samples_per_period: int) -> QoSProfile:
    """Reliable, several periods deep: the lock-step loop needs every sample (never dropped)."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=max(1024, 8 * samples_per_period),
        reliability=ReliabilityPolicy.RELIABLE,
    )


class WaveletFilterbankNode(Node):
    """Publish the wavelet coefficients of the measurement stream (module docstring)."""

    def __init__(self) -> None:
        super().__init__("wavelet_filterbank")
        ro = {"read_only": True}
        self.declare_parameter(
            "wavelet", "haar", ParameterDescriptor(description="PyWavelets name (orthogonal)", **ro)
        )
        self.declare_parameter(
            "samples_per_rev",
            64,
            ParameterDescriptor(
                description="samples per revolution, power of two",
                integer_range=[IntegerRange(from_value=4, to_value=4096)],
                **ro,
            ),
        )
        self.declare_parameter(
            "samples_per_period",
            0,
            ParameterDescriptor(
                description="control period in samples (0 = samples_per_rev)",
                integer_range=[IntegerRange(from_value=0, to_value=65536)],
                **ro,
            ),
        )
        self.declare_parameter(
            "levels",
            0,
            ParameterDescriptor(
                description="filterbank levels J (0 = log2(samples_per_rev) + 1: down to 0.5 x)",
                integer_range=[IntegerRange(from_value=0, to_value=16)],
                **ro,
            ),
        )
        self.declare_parameter(
            "frames", list(FRAMES), ParameterDescriptor(description="fixed, rotating", **ro)
        )
        self.declare_parameter(
            "quadrature", list(QUADRATURES), ParameterDescriptor(description="even, odd", **ro)
        )
        self.declare_parameter(
            "quarter_delay",
            0,
            ParameterDescriptor(
                description="odd-channel delay in samples (0 = samples_per_rev / 4)",
                integer_range=[IntegerRange(from_value=0, to_value=65536)],
                **ro,
            ),
        )
        self.declare_parameter(
            "status_period",
            1.0,
            ParameterDescriptor(
                description="period of the /diagnostics report, s (wall clock)",
                floating_point_range=[FloatingPointRange(from_value=0.05, to_value=60.0)],
            ),
        )
        self._configure()
        qos = stream_qos(self._samples_per_period)
        self._pub = self.create_publisher(WaveletCoefficients, "/amb/wavelet/coefficients", qos)
        self._diag = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_subscription(Measurement, "/amb/measurement", self._on_measurement, qos)
        self.create_timer(self.get_parameter("status_period").value, self._publish_status)
        self.samples = self.published = self.gaps = self.repeats = self.rejected = 0
        self._last_reason = ""
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
        self._expected: int | None = None

    def _reject(self, reason: str) -> None:
        self.rejected += 1
        self._last_reason = reason
        self.get_logger().warning(reason, throttle_duration_sec=5.0)

    def _on_measurement(self, msg: Measurement) -> None:
        xy = msg.displacement
        if not (np.all(np.isfinite(xy)) and math.isfinite(msg.rotor_angle)):
            self._reject(f"sample {msg.sample_index}: non-finite displacement or angle, dropped")
            return
        index = msg.sample_index
        if self._expected is not None and index != self._expected:
            if index == self._expected - 1:
                self.repeats += 1
                self._last_reason = f"sample {index} repeated, dropped"
                return
            self.gaps += 1
            self._last_reason = (
                f"sample {index} after {self._expected - 1}: filterbank reset at {index}"
            )
            self.get_logger().warning(self._last_reason, throttle_duration_sec=5.0)
            self._expected = None
        if self._expected is None:
            self._front.reset()
            self._bank.reset(start_sample_index=index)
        self._expected = index + 1
        self.samples += 1
        coefficients = self._bank.step(self._front.step(xy, msg.rotor_angle), index)
        if not coefficients:
            return
        out = coefficients_msg(
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
        if self.rejected or self.gaps:
            level = DiagnosticStatus.WARN
        values = {
            "samples": self.samples,
            "messages_published": self.published,
            "gaps_reset": self.gaps,
            "repeats_dropped": self.repeats,
            "rejected": self.rejected,
            "wavelet": self._wavelet,
            "levels": self._levels,
        }
        status = DiagnosticStatus(
            level=level,
            name="wavelet_filterbank",
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
