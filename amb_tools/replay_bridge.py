"""``replay_bridge``: a second implementation of the plant's interface, from a recorded bag.

It stands where ``plant_sim`` or a hardware I/O bridge stands: it publishes the recorded
``/amb/measurement`` stream on the wall clock (paced by the messages' header stamps, times
``time_scale``), subscribes ``/amb/control/command`` and writes every command it receives to a
JSON-lines log (period, based-on period, arrival lateness relative to the target period's first
sample, peak force per axis). It never applies the commands: the measurements are the bag's. This
shows, and tests, that the filterbank, the fault monitor and the controller need nothing from the
plant but the interface of ARCHITECTURE.md (``realtime`` mode: the bridge owns time, commands are
applied when they arrive, late ones are counted by the receiver). At the end it waits (10 s at
most) for the commands answering the last measured periods, then exits with status 0.

Parameters
----------
bag : str
    rosbag2 folder holding ``/amb/measurement`` (any bag of this project or ``ros2 bag record``;
    recorded under a namespace, ``/rig1/amb/measurement``, too: the one namespace under which the
    bag holds the measurement stream, :func:`amb_common.topics.bag_namespace`). The bridge
    publishes on its own namespace's ``amb/measurement``, whatever the bag's was.
time_scale : float
    Simulated s per wall s (1.0 = as recorded).
command_log : str
    JSON-lines file for the received commands ('' = log to the console only).
wait_for_subscribers : int
    Subscribers of ``/amb/measurement`` to wait for before the first sample.
startup_timeout : float
    Wall s to wait for them.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
from amb_msgs.msg import ControlCommand, Measurement
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from rosbags.rosbag2 import Reader

from amb_common import topics
from amb_common.names import N_AXES
from amb_tools.conversions import from_float_array, stamp_seconds
from amb_tools.node_main import ConfigurationError, descriptor, run_node
from amb_tools.streams import COMMAND_QOS, stream_qos


class ReplayBridge(Node):
    """Publish a recorded measurement stream; log the commands that come back."""

    def __init__(self) -> None:
        super().__init__("replay_bridge")
        d = self.declare_parameter
        d("bag", "", descriptor("rosbag2 folder"))
        d("time_scale", 1.0, descriptor("simulated s per wall s", floats=(0.01, 100.0)))
        d("command_log", "", descriptor("JSON-lines command log"))
        d("wait_for_subscribers", 1, descriptor("subscribers to wait for", ints=(0, 64)))
        d("startup_timeout", 30.0, descriptor("wall s", floats=(0.0, 600.0)))
        bag = self.get_parameter("bag").value
        if not bag or not Path(bag).is_dir():
            raise ConfigurationError(f"parameter 'bag' = {bag!r}: not a rosbag2 folder")
        self._samples = self._load(Path(bag))
        if not self._samples:
            raise ConfigurationError(
                f"parameter 'bag' = {bag!r}: no {topics.MEASUREMENT} messages (in any namespace)"
            )
        spr = self._samples[0][1].samples_per_rev
        self._pub = self.create_publisher(Measurement, topics.MEASUREMENT, stream_qos(spr))
        self.create_subscription(ControlCommand, topics.COMMAND, self._on_command, COMMAND_QOS)
        log = self.get_parameter("command_log").value
        self._log = open(log, "w") if log else None
        self._scale = self.get_parameter("time_scale").value
        self._deadline = time.monotonic() + self.get_parameter("startup_timeout").value
        self._next = 0
        self._wall0: float | None = None
        self._t0 = self._samples[0][0]
        self.commands = 0
        self._last_based_on = -1
        last = self._samples[-1][1]
        self._last_period = (last.sample_index + 1) // last.samples_per_rev - 1
        self._end_wall: float | None = None
        self.done = False
        self.create_timer(0.002, self._tick)
        self.get_logger().info(f"replaying {len(self._samples)} samples from {bag}")

    @staticmethod
    def _load(bag: Path) -> list[tuple[float, Measurement]]:
        out = []
        with Reader(bag) as reader:
            try:
                ns = topics.bag_namespace(c.topic for c in reader.connections)
            except ValueError as exc:
                raise ConfigurationError(f"parameter 'bag' = {str(bag)!r}: {exc}") from exc
            wanted = topics.absolute(topics.MEASUREMENT, ns)
            conns = [c for c in reader.connections if c.topic == wanted]
            for _conn, _t, raw in reader.messages(connections=conns):
                msg = deserialize_message(bytes(raw), Measurement)
                out.append((stamp_seconds(msg.header.stamp), msg))
        return out

    def _tick(self) -> None:
        if self.done:
            return
        if self._wall0 is None:
            want = self.get_parameter("wait_for_subscribers").value
            if self._pub.get_subscription_count() < want and time.monotonic() < self._deadline:
                return
            self._wall0 = time.monotonic()
        due = self._t0 + (time.monotonic() - self._wall0) * self._scale
        while self._next < len(self._samples) and self._samples[self._next][0] <= due:
            self._pub.publish(self._samples[self._next][1])
            self._next += 1
        if self._next == len(self._samples):
            if self._end_wall is None:
                self._pub.wait_for_all_acked(Duration(seconds=10.0))
                self._end_wall = time.monotonic()
            # commands for the last measured periods are still on their way: wait for them
            if self._last_based_on < self._last_period and time.monotonic() - self._end_wall < 10.0:
                return
            self.get_logger().info(
                f"replay complete: {self._next} samples published, "
                f"{self.commands} commands received"
            )
            self.done = True

    def _on_command(self, msg: ControlCommand) -> None:
        self.commands += 1
        self._last_based_on = max(self._last_based_on, int(msg.based_on_period))
        force = from_float_array(msg.force)
        n = msg.samples_per_period or 1
        peaks = (
            np.max(np.abs(force.reshape(N_AXES, n)), axis=1).tolist()
            if force.size == N_AXES * n
            else []
        )
        published = self._samples[self._next - 1][1].sample_index if self._next else -1
        entry = {
            "period_index": msg.period_index,
            "based_on_period": msg.based_on_period,
            "start_sample_index": msg.start_sample_index,
            "samples_ahead": int(msg.start_sample_index) - int(published) - 1,
            "peak_force": peaks,
            "hold": msg.hold,
        }
        if self._log is not None:
            self._log.write(json.dumps(entry) + "\n")
            self._log.flush()

    def on_shutdown(self) -> None:
        """Close the command log."""
        if self._log is not None:
            self._log.close()


def main(args: list[str] | None = None) -> int:
    """Entry point of the ``replay_bridge`` executable."""
    return run_node(ReplayBridge, args)


if __name__ == "__main__":
    raise SystemExit(main())
