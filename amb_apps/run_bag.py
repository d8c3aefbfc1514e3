"""
A closed-loop run written as a rosbag2: the ROS pipeline's topics and types.

The messages are built by the builders of :mod:`amb_tools.conversions` and
:mod:`amb_wavelet.messages` and serialised with ``rclpy.serialization.serialize_message`` (the
bytes the nodes publish); the bag time of every message is its header stamp (simulated time).
rclpy and the messages are imported only when a bag is written (:class:`BagRecorder`'s
constructor and methods), so :mod:`amb_apps.closed_loop` runs without ROS.
"""

from __future__ import annotations

from pathlib import Path
from typing import ClassVar

import numpy as np

from amb_common import topics
from amb_controller.config import ControllerConfig
from amb_controller.pipeline import ControllerPipeline
from amb_controller.selection import control_waveform
from amb_controller.supervisor import Command
from amb_wavelet.frontend import FRAMES, QUADRATURES

__all__ = ["BagRecorder"]


class BagRecorder:
    """
    Write the run as the ROS pipeline's topics (same builders, same serialisation).

    Parameters
    ----------
    path : str or Path
        Bag folder to create (must not exist).
    config : ControllerConfig
        For the coefficient slots and message fields.
    force_limit : float
        Bearing capacity in N (``Measurement.STATUS_FORCE_SATURATED``).

    """

    #: The streams under their canonical absolute names (the root namespace: ``/amb/...``), as
    #: the nodes started without a namespace publish them.
    TOPICS: ClassVar[dict[str, str]] = topics.stream_types()
    #: Each stream's relative name (:mod:`amb_common.topics`) -> its name in the bag.
    TOPIC: ClassVar[dict[str, str]] = {t: topics.absolute(t) for t in topics.STREAM_TYPES}

    def __init__(self, path: str | Path, config: ControllerConfig, force_limit: float) -> None:
        # heavy, optional: ROS messages and rclpy/rosbags, only when the loop records a bag
        from amb_msgs.msg import CoefficientSet as CoefficientSetMsg
        from rclpy.serialization import serialize_message

        from amb_tools.bag_writer import BagWriter

        self._serialize = serialize_message
        self.writer = BagWriter(path)
        for topic, msgtype in self.TOPICS.items():
            self.writer.add_topic(topic, msgtype)
        self.config = config
        self.force_limit = float(force_limit)
        frame = {
            "fixed": CoefficientSetMsg.FRAME_FIXED,
            "rotating": CoefficientSetMsg.FRAME_ROTATING,
        }
        quad = {"even": CoefficientSetMsg.QUADRATURE_EVEN, "odd": CoefficientSetMsg.QUADRATURE_ODD}
        self.slots = [(frame[f], quad[q]) for f in FRAMES for q in QUADRATURES]

    def _write(self, topic: str, msg) -> None:
        st = msg.header.stamp
        self.writer.write_raw(topic, st.sec * 1_000_000_000 + st.nanosec, self._serialize(msg))

    def measurements(self, block, force: np.ndarray) -> list:
        """Write the block's ``Measurement`` messages; return them (for their headers)."""
        # heavy, optional: ROS messages and rclpy/rosbags, only when the loop records a bag
        from amb_tools.conversions import measurement_msgs

        msgs = measurement_msgs(block, force, 0, self.config.samples_per_rev, self.force_limit)
        for m in msgs:
            self._write(self.TOPIC[topics.MEASUREMENT], m)
        return msgs

    def coefficients(self, measurement, sample_index: int, omega: float, records) -> None:
        """Write the ``WaveletCoefficients`` of one sample."""
        # heavy, optional: ROS messages and rclpy/rosbags, only when the loop records a bag
        from amb_wavelet.messages import coefficients_msg

        cfg = self.config
        msg = coefficients_msg(
            measurement.header, cfg.wavelet, cfg.samples_per_rev, cfg.period_samples,
            sample_index, omega, records, self.slots,
        )  # fmt: skip
        self._write(self.TOPIC[topics.COEFFICIENTS], msg)

    def command(self, command: Command, header, pipeline: ControllerPipeline) -> None:
        """Write a ``ControlCommand`` and the ``ControllerStatus`` after it."""
        # heavy, optional: ROS messages and rclpy/rosbags, only when the loop records a bag
        from amb_tools.conversions import command_msg, controller_status_msg

        cfg = self.config
        self._write(
            self.TOPIC[topics.COMMAND],
            command_msg(
                command, header, pipeline.control.labels, cfg.period_samples,
                cfg.delay_periods, control_waveform(cfg),
            ),
        )  # fmt: skip
        self._write(self.TOPIC[topics.STATUS], controller_status_msg(pipeline.status(), header))

    def fault_event(self, event: dict, stamp) -> None:
        """Write a ``FaultEvent`` (fields of :class:`amb_common.faults.FaultEvent`)."""
        # heavy, optional: ROS messages and rclpy/rosbags, only when the loop records a bag
        from amb_msgs.msg import FaultEvent
        from diagnostic_msgs.msg import KeyValue

        msg = FaultEvent()
        msg.header.stamp = stamp
        msg.header.frame_id = "amb_rig"
        msg.event_id = int(event.get("event_id", 0))
        msg.fault_type = int(event["fault_type_code"])
        msg.onset_sample_index = int(event["onset_sample_index"])
        msg.detection_sample_index = int(event["detection_sample_index"])
        msg.plane = int(event.get("plane", 0))
        msg.channel = int(event.get("channel", -1))
        msg.bearing = int(event.get("bearing", 0))
        msg.severity = float(event.get("severity", 0.0))
        msg.confidence = float(event.get("confidence", 0.0))
        msg.count = int(event.get("count", 1))
        msg.rotor_speed = float(event.get("omega", 0.0))
        msg.evidence = [KeyValue(key=str(k), value=str(v)) for k, v in event["evidence"].items()]
        msg.description = str(event.get("description", ""))
        msg.detection_stamp = stamp
        self._write(self.TOPIC[topics.FAULT_EVENTS], msg)

    def close(self) -> None:
        """Finish the bag."""
        self.writer.close()
