"""``wavelet_controller``: wavelet-domain control of the rotor (thesis chapters 6-8) on ROS 2.

A thin ROS layer over :class:`amb_controller.pipeline.ControllerPipeline`. It reads
``/amb/measurement`` and ``/amb/wavelet/coefficients``, feeds the pipeline sample by sample in
index order, and at the last sample of every measured period m publishes exactly one
``ControlCommand`` for period ``m + delay_periods`` on ``/amb/control/command`` (zero force when
OFF, so the plant's lock-step loop keeps running) and a ``ControllerStatus`` on
``/amb/control/status``.

Joining the two streams
-----------------------
Every sample ``n`` has a ``Measurement``; the filterbank publishes a ``WaveletCoefficients``
message exactly for odd ``n`` (its finest level completes every second sample). Sample ``n`` is
processed once its measurement and, for odd ``n``, its coefficients are in, whatever order DDS
delivered them in, so the commands equal the in-process runner's (``amb-sim``) bit for bit. If a
coefficient message is lost (a later one arrived first: each topic is delivered in order), the
sample is processed without it and the pipeline answers that period with zero force.

Services: ``/amb/control/set_mode`` (``SetControllerMode``),
``/amb/control/start_identification`` (``StartIdentification``; the identified model is written
to ``model_file_out`` or the request's ``model_file``). ``FaultEvent`` messages on
``/amb/fault/events`` trigger the configured fault actions (e.g. HOLD on auxiliary-bearing
contact). All parameters are validated at start-up (``ControllerConfig``): an invalid value
stops the node with exit status 2 and a message naming the parameter, the value and the range.
"""

from __future__ import annotations

import math
from collections import deque
from pathlib import Path

from amb_msgs.msg import (
    ControlCommand,
    ControllerStatus,
    FaultEvent,
    Measurement,
    WaveletCoefficients,
)
from amb_msgs.srv import SetControllerMode, StartIdentification
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from amb_controller.errors import ControllerValueError
from amb_controller.pipeline import ControllerConfig, ControllerPipeline
from amb_controller.supervisor import Mode
from amb_plant_sim.errors import RigError
from amb_plant_sim.rig import load_rig
from amb_tools.conversions import (
    MessageError,
    coefficient_records,
    command_msg,
    controller_status_msg,
)
from amb_tools.node_main import ConfigurationError, run_node
from amb_tools.paths import config_file
from amb_wavelet.frontend import FRAMES, QUADRATURES, ChannelFrontEnd
from amb_wavelet.node import FRAME_CODES, QUAD_CODES, stream_qos

COMMAND_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=16, reliability=ReliabilityPolicy.RELIABLE
)
START_MODES = ("off", "active", "identify")

# ROS parameter -> (default, description). Defaults equal ControllerConfig's; bounds of 0.0
# mean "off" for the guards (ROS parameters cannot hold inf).
PARAMETERS: dict[str, tuple[object, str]] = {
    "wavelet": ("haar", "PyWavelets name (analysis and control)"),
    "samples_per_rev": (64, "samples per revolution, power of two"),
    "samples_per_period": (0, "control period in samples (0 = samples_per_rev)"),
    "levels": ([1], "thesis levels p (1 = 1 x running speed)"),
    "quadratures": (["even", "odd"], "quadrature channels (section 4.3)"),
    "sensors": ([2, 3, 4, 5], "sensor channels 0..7 measured (default: the inner planes)"),
    "delay_periods": (2, "evaluation delay i, periods (eq. 8.10)"),
    "controller": ("transient", "none | proportional | moderated | transient"),
    "response": ("exponential", "exponential (w, v) | linear (rate) | series"),
    "w": (0.75, "exponential response gain w, 0 < w < 1 (eq. 8.6)"),
    "v": (0.75, "exponential response pole v, 0 <= v < 1 (eq. 8.6)"),
    "rate": (0.2, "linear decay per period"),
    "series": ([0.0], "c_1..c_K of eq. 8.7 (response series; [0.0] = unused)"),
    "gain": (0.21, "dimensionless k of the proportional/moderated controllers"),
    "inverse_order": (5, "truncation order of the pseudo-inverse (eq. 6.35)"),
    "inverse_regularisation": (0.0, "Tikhonov weight of the inverse"),
    "predictor_dc_weight": (10.0, "weight of B(1) G(1) = I in the predictor (eq. 7.6)"),
    "force_limit": ([1000.0] * 4, "wavelet force limit per axis, N (<= bearing capacity)"),
    "coefficient_bound": (0.0, "guard: any measured coefficient, m sqrt(samples) (0 = off)"),
    "displacement_bound": (0.0, "guard: peak displacement of a period, m (0 = off)"),
    "growth_factor": (1.5, "guard: per-period growth ratio counted as divergence"),
    "growth_periods": (8, "guard: consecutive growing periods that trip it"),
    "fault_actions": (["2:hold"], "FaultEvent type:action (hold | off | ignore)"),
    "model_file": ("", "wavelet model .npz to load at start ('' = none)"),
    "identification_order": (12, "Markov order fitted by identification"),
    "identification_amplitude": (20.0, "default step, N sqrt(samples)"),
    "identification_periods_per_step": (16, "default periods per identification step"),
}


def config_from_parameters(values: dict) -> dict:
    """Map the node's parameter values onto ``ControllerConfig`` fields."""
    d = dict(values)
    for bound in ("coefficient_bound", "displacement_bound"):
        if d[bound] == 0.0:
            d[bound] = math.inf
    if list(d["series"]) == [0.0]:
        d["series"] = ()
    actions = {}
    for item in d["fault_actions"]:
        code, _, action = str(item).partition(":")
        try:
            actions[int(code)] = action
        except ValueError as exc:
            raise ConfigurationError(
                f"parameter 'fault_actions' entry {item!r}: expected 'TYPE:ACTION', e.g. '2:hold'"
            ) from exc
    d["fault_actions"] = actions
    return d


class WaveletControllerNode(Node):
    """The wavelet controller (module docstring)."""

    def __init__(self) -> None:
        super().__init__("wavelet_controller")
        for name, (default, description) in PARAMETERS.items():
            self.declare_parameter(
                name, default, ParameterDescriptor(description=description, read_only=True)
            )
        self.declare_parameter(
            "rig_file",
            "",
            ParameterDescriptor(description="rig YAML ('' = package's)", read_only=True),
        )
        self.declare_parameter(
            "start_mode",
            "off",
            ParameterDescriptor(
                description="off | active | identify (on-line identification from the start, "
                "model written to model_file_out)",
                read_only=True,
            ),
        )
        self.declare_parameter(
            "model_file_out",
            "",
            ParameterDescriptor(description="where identification writes the model ('' = none)"),
        )
        self._configure()
        qos = stream_qos(self._pipe.samples_per_period)
        self._cmd_pub = self.create_publisher(ControlCommand, "/amb/control/command", COMMAND_QOS)
        self._status_pub = self.create_publisher(ControllerStatus, "/amb/control/status", 10)
        self.create_subscription(Measurement, "/amb/measurement", self._on_measurement, qos)
        self.create_subscription(
            WaveletCoefficients, "/amb/wavelet/coefficients", self._on_coefficients, qos
        )
        self.create_subscription(FaultEvent, "/amb/fault/events", self._on_fault, 10)
        self.create_service(SetControllerMode, "/amb/control/set_mode", self._on_set_mode)
        self.create_service(
            StartIdentification, "/amb/control/start_identification", self._on_identify
        )
        self._measurements: dict[int, Measurement] = {}
        self._coefficients: deque[WaveletCoefficients] = deque()
        self._next: int | None = None

    def _configure(self) -> None:
        values = {name: self.get_parameter(name).value for name in PARAMETERS}
        rig_file = self.get_parameter("rig_file").value or str(config_file("rig.yaml"))
        try:
            capacity = load_rig(rig_file).amb.force_limit
        except RigError as exc:
            raise ConfigurationError(f"parameter 'rig_file' = {rig_file!r}: {exc}") from exc
        try:
            config = ControllerConfig.from_dict(config_from_parameters(values), capacity)
            front = ChannelFrontEnd(config.samples_per_rev)
            self._pipe = ControllerPipeline(config, capacity, channel_labels=front.labels)
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
            if not ok:
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

    # ------------------------------------------------------------------ streams
    def _on_measurement(self, msg: Measurement) -> None:
        n = msg.sample_index
        if self._next is None or n < self._next:  # first sample, or the plant restarted
            if self._next is not None:
                self.get_logger().warning(f"sample {n} after {self._next - 1}: restart")
                self._measurements.clear()
                self._coefficients.clear()
            self._next = n
        self._measurements[n] = msg
        self._drain()

    def _on_coefficients(self, msg: WaveletCoefficients) -> None:
        self._coefficients.append(msg)
        self._drain()

    def _drain(self) -> None:
        while self._next is not None and self._next in self._measurements:
            n = self._next
            coeffs = None
            while self._coefficients and self._coefficients[0].sample_index < n:
                self._coefficients.popleft()  # belongs to samples before a restart
            if self._coefficients and self._coefficients[0].sample_index == n:
                coeffs = self._coefficients.popleft()
            elif n % 2 == 1 and not self._coefficients:
                return  # wait for the coefficients of this sample
            self._process(self._measurements.pop(n), coeffs)
            self._next = n + 1

    def _process(self, m: Measurement, coeffs: WaveletCoefficients | None) -> None:
        records = []
        if coeffs is not None:
            try:
                records = coefficient_records(coeffs, self._slots)
            except MessageError as exc:
                self._pipe._stats["inputs_rejected"] += 1
                self.get_logger().warning(str(exc), throttle_duration_sec=5.0)
        command = self._pipe.on_sample(m.sample_index, records, m.displacement, m.rotor_speed)
        if command is None:
            return
        cfg = self._pipe.config
        self._cmd_pub.publish(
            command_msg(
                command,
                m.header,
                self._pipe.control.labels,
                self._pipe.samples_per_period,
                cfg.delay_periods,
                cfg.wavelet,
            )
        )
        self._status_pub.publish(controller_status_msg(self._pipe.status(), m.header))
        if self._identifying and self._pipe.supervisor.mode != Mode.IDENTIFYING:
            self._identifying = False
            self._write_model()

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

    # ------------------------------------------------------------------ services, events
    def _on_fault(self, msg: FaultEvent) -> None:
        action = self._pipe.on_fault(msg.fault_type)
        self.get_logger().info(f"fault event type {msg.fault_type}: {action}")

    def _on_set_mode(self, request, response):
        response.accepted, response.message = self._pipe.set_mode(request.mode)
        response.mode = int(self._pipe.supervisor.mode)
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
