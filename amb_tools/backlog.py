"""
Catching up after an overload: a stream reader that drops the oldest of a long backlog.

In ``realtime`` a node that falls behind the measurement stream (a CPU hog, a stopped process,
a slow disk under a composed recorder) finds its queue full of samples whose control periods
are over: processing them in order keeps it behind for as long as the backlog takes to drain,
and at a load close to one core that is for good. A :class:`BacklogReader` takes every queued
message at each wake (rclpy's executors hand them over one per callback) and, when more than
``max_backlog`` are waiting, drops the oldest and keeps the newest ``max_backlog``: one counted,
logged gap per overload instead of a backlog that never drains. The readers downstream see an
ordinary discontinuity (:class:`amb_tools.validation.SampleSequencer`: the filterbank resets at
the new index, the controller resets its filters, the fault monitor calibrates again) once per
episode, not once per late sample.

``max_backlog = 0`` (the default) keeps every sample: ``lockstep`` needs all of them and is
never behind by more than the periods the plant waits for. Every node that reads the
measurement stream declares the parameter (:func:`declare_max_backlog`) and bounds with it
its DDS readers of both streams (the controller and the monitor read the coefficients too, about
one message per two samples); composed in one process (:mod:`amb_tools.local_bus`) the nodes
share one measurement reader, which takes the value of the first (the filterbank's), and the
coefficients are handed over in-process, never queued.
"""

from __future__ import annotations

from collections.abc import Callable

from rclpy.node import Node
from rclpy.qos import QoSProfile

from amb_tools.node_main import descriptor
from amb_tools.throttled_log import ThrottledWarnings

__all__ = ["MAX_BACKLOG", "BacklogReader", "backlog_counts", "declare_max_backlog"]

#: Name of the ROS parameter (samples; 0 = keep every sample).
MAX_BACKLOG = "max_backlog"


def declare_max_backlog(node: Node) -> int:
    """
    Declare ``max_backlog`` on ``node`` (read-only, samples) and return its value.

    Returns
    -------
    int
        Samples kept behind the newest when the reader is behind; 0: keep every sample.
    """
    node.declare_parameter(
        MAX_BACKLOG,
        0,
        descriptor(
            "realtime catch-up: with more stream messages (measurements, coefficients) queued "
            "than this, the oldest are dropped and the newest max_backlog kept (a counted gap); "
            "0 = keep every message (lockstep)",
            ints=(0, 1 << 20),
        ),
    )
    return int(node.get_parameter(MAX_BACKLOG).value)


class BacklogReader:
    """
    A raw DDS subscription that hands over its messages in order, dropping a long backlog.

    Parameters
    ----------
    node : rclpy.node.Node
        The node holding the subscription.
    msg_type : type
        Message class.
    name : str
        Topic name.
    deliver : callable
        Called with the CDR bytes of each message kept, oldest first.
    qos : rclpy.qos.QoSProfile
        QoS of the subscription.
    max_backlog : int
        Messages kept when more are queued; 0: every message is delivered, one per wake.
    on_dropped : callable, optional
        Called with the CDR bytes of each message dropped, oldest first, before the kept ones
        are delivered (a reader that must lose nothing: a composed recorder).

    Attributes
    ----------
    dropped : int
        Messages dropped so far.
    episodes : int
        Wakes that dropped messages (overloads caught up).
    """

    def __init__(
        self,
        node: Node,
        msg_type: type,
        name: str,
        deliver: Callable[[bytes], None],
        qos: QoSProfile,
        max_backlog: int = 0,
        on_dropped: Callable[[bytes], None] | None = None,
    ) -> None:
        if max_backlog < 0:
            raise ValueError(f"max_backlog = {max_backlog}: must be >= 0 (0 = keep every sample)")
        self._deliver = deliver
        self._on_dropped = on_dropped
        self._msg_type = msg_type
        self.max_backlog = int(max_backlog)
        self.dropped = self.episodes = 0
        self._warnings = ThrottledWarnings(node.get_logger(), period=5.0)
        # without a bound each message goes straight to ``deliver``: no extra call per message
        callback = self._on_message if self.max_backlog else deliver
        self.subscription = node.create_subscription(msg_type, name, callback, qos, raw=True)

    def _on_message(self, raw: bytes) -> None:
        batch = [raw]
        sub = self.subscription
        with sub.handle:  # as rclpy's executors take: every message queued now
            while (taken := sub.handle.take_message(self._msg_type, True)) is not None:
                batch.append(taken[0])
        excess = len(batch) - self.max_backlog
        if excess > 0:
            self.dropped += excess
            self.episodes += 1
            self._warnings.warning(
                "backlog",
                f"{sub.topic_name}: {len(batch)} messages queued, more than max_backlog = "
                f"{self.max_backlog}: the oldest {excess} dropped to catch up "
                f"({self.dropped} in {self.episodes} overloads so far)",
            )
            if self._on_dropped is not None:
                for item in batch[:excess]:
                    self._on_dropped(item)
            del batch[:excess]
        for item in batch:
            self._deliver(item)


def backlog_counts(*readers: BacklogReader | None) -> dict[str, int]:
    """The ``/diagnostics`` values of a node's readers: messages dropped behind, overloads.

    Summed over the readers given (None: a stream handed over in-process, never behind).
    """
    own = [r for r in readers if r is not None]
    return {
        "backlog_dropped": sum(r.dropped for r in own),
        "backlog_overloads": sum(r.episodes for r in own),
    }
