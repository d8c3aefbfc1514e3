"""A separate process for transport tests: re-publishes every amb_msgs type unchanged.

For each message type ``T`` of ``amb_msgs`` it subscribes (raw CDR) to ``/amb_test/in/T`` and
publishes the same bytes on ``/amb_test/out/T``, so a test in another process can check that a
message crossed DDS twice intact. Reliable, keep-all QoS. Stops on SIGINT or SIGTERM.

What arrives before the relay's own writer has matched a reader is held and sent once it has:
the test seeing the relay's writer (its reader's count) does not mean the writer sees the test's
reader yet, and a volatile writer's messages before that match are lost (a fresh-clone run lost
every ControllerStatus so).
"""

from __future__ import annotations

import sys
from pathlib import Path

import amb_msgs.msg
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from amb_tools.node_main import run_node

QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=1000, reliability=ReliabilityPolicy.RELIABLE)


def message_classes() -> list[type]:
    """All message classes of amb_msgs."""
    return [
        getattr(amb_msgs.msg, name)
        for name in dir(amb_msgs.msg)
        if not name.startswith("_") and hasattr(getattr(amb_msgs.msg, name), "SLOT_TYPES")
    ]


class _Forward:
    """Publish each raw message on ``pub`` once it has a matched reader; hold it until then."""

    def __init__(self, pub) -> None:
        self.pub = pub
        self.held: list[bytes] = []

    def __call__(self, raw: bytes | None = None) -> None:
        if raw is not None:
            self.held.append(raw)
        if self.held and self.pub.get_subscription_count() > 0:
            for held in self.held:
                self.pub.publish(held)
            self.held.clear()


class Relay(Node):
    def __init__(self) -> None:
        super().__init__("amb_test_relay")
        self.relays = []
        forwards = []
        for cls in message_classes():
            forward = _Forward(self.create_publisher(cls, f"/amb_test/out/{cls.__name__}", QOS))
            forwards.append(forward)
            self.relays.append(
                self.create_subscription(
                    cls, f"/amb_test/in/{cls.__name__}", forward, QOS, raw=True
                )
            )
        self.create_timer(0.02, lambda: [f() for f in forwards])


if __name__ == "__main__":
    raise SystemExit(run_node(Relay))
