"""
Publications that wait for a slow reader instead of overwriting what it has not yet got.

A reliable writer with KEEP_LAST history keeps the last ``depth`` messages for its readers. A
reader whose process is descheduled or stopped for longer than that, in messages, loses the
overwritten ones for good: the demo's recorder (niced, on a 2-core machine beside a lock-step
loop publishing about ten times faster than real time) missed 75 and 240 of 18688 measurements
in two of three runs, and a recorder stopped for 1.5 s in such a run lost 7616 measurements,
3325 coefficient messages and 120 commands (``docs/history.md``, "The recorder in lock-step").

In ``lockstep`` nothing may be lost and nothing is ever late, so the nodes' stream writers
there keep every message until each reader has acknowledged it (KEEP_ALL history), and a
publication that finds the writer's history full (Fast DDS: ``resource_limits.max_samples``,
5000 messages by default) waits until a reader's acknowledgement makes room: the slow reader
paces the loop. Fast DDS blocks such a ``write`` for ``reliability.max_blocking_time`` (100 ms
by default) and then fails it without sending anything; :class:`WaitingPublisher` tries again
until it succeeds, and raises only what is not a full history (no reader matched, the context
shut down). A reader that died without leaving (SIGKILL) holds the writer until its
participant's lease runs out (measured: 19.4 s with Fast DDS's 20 s default).

A reader's process can also hold a writer inside ``write`` itself: Fast DDS's shared-memory
transport guards each reader's port with a mutex shared between processes, which the reader's
listener thread holds while it takes a message from the port; stopped (or descheduled) there,
it blocks every writer that pushes to that port, in every process, until it runs again (seen
with ``gdb``: the plant's ``publish`` waiting in ``SharedMemManager::Port::try_push`` on the
mutex whose owner was the stopped recorder's ``dds.shm`` thread; ``docs/history.md``, "A
stopped reader that blocks its writers"). Nothing is lost then either; a publication that took
longer than :data:`BLOCKED_AFTER_S` is counted and logged as a wait like the others.

In ``realtime`` the writers stay KEEP_LAST: the control path never waits for a reader, and a
reader that far behind loses the oldest messages as ``max_backlog`` drops them on the reading
side. Which nodes wait: the plant in ``lockstep``, the other nodes while they keep every
message they read (``max_backlog`` 0, :attr:`amb_tools.backlog.CatchUp.keeps_every_message`).
"""

from __future__ import annotations

import time
from typing import Any

from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile

__all__ = ["WAITED_KEY", "WaitingPublisher", "keep_all", "publisher"]

#: Diagnostics key of the wall time a writer's publications waited: ``WAITED_KEY + topic``.
WAITED_KEY = "publication waited s "
#: Seconds a publication waits before it is warned of (a recorder's usual lag is shorter).
WARN_AFTER_S = 1.0
#: Seconds between the warnings of one long wait (a reader that died holds it about 20 s).
WARN_PERIOD_S = 5.0
#: Seconds one ``write`` may take before it counts as a wait (module notes); ordinarily it takes
#: about 0.1 ms, and a full history makes Fast DDS give up after its 100 ms blocking time.
BLOCKED_AFTER_S = 0.5


def keep_all(qos: QoSProfile) -> QoSProfile:
    """
    ``qos`` with KEEP_ALL history (every other policy as given).

    Parameters
    ----------
    qos : rclpy.qos.QoSProfile
        A reliable profile (KEEP_ALL of a best-effort writer would keep nothing longer).

    Returns
    -------
    rclpy.qos.QoSProfile
        A new profile; ``qos`` is left as it was.
    """
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL,
        depth=qos.depth,
        reliability=qos.reliability,
        durability=qos.durability,
    )


class WaitingPublisher:
    """
    A KEEP_ALL publisher whose :meth:`publish` waits while its history is full (module notes).

    Parameters
    ----------
    node : rclpy.node.Node
        The node that publishes.
    msg_type : type
        Message class.
    name : str
        Topic name.
    qos : rclpy.qos.QoSProfile
        The stream's QoS; its history is made KEEP_ALL (:func:`keep_all`).

    Attributes
    ----------
    waits : int
        Publications that found the history full and waited.
    waited_s : float
        Wall seconds those publications waited in all.
    """

    def __init__(self, node: Node, msg_type: type, name: str, qos: QoSProfile) -> None:
        self._pub = node.create_publisher(msg_type, name, keep_all(qos))
        self._context = node.context
        self._logger = node.get_logger()
        self.waits = 0
        self.waited_s = 0.0

    @property
    def topic_name(self) -> str:
        """The resolved topic name."""
        return self._pub.topic_name

    def get_subscription_count(self) -> int:
        """Readers matched by the writer (:meth:`rclpy.publisher.Publisher`'s)."""
        return self._pub.get_subscription_count()

    def wait_for_all_acked(self, timeout: Any) -> bool:
        """Whether every reader acknowledged every message within ``timeout`` (a Duration)."""
        return self._pub.wait_for_all_acked(timeout)

    def publish(self, msg: Any) -> None:
        """
        Publish ``msg`` (a message or its CDR bytes), waiting while the history is full.

        Raises
        ------
        rclpy._rclpy_pybind11.RCLError
            A failure that is not a full history: no reader is matched, or the context is
            shut down.
        """
        start = time.monotonic()
        waiting = False
        warn_at = start + WARN_AFTER_S
        while True:
            tried = time.monotonic()
            try:
                self._pub.publish(msg)
            except _rclpy.RCLError:
                if not self._context.ok() or self._pub.get_subscription_count() == 0:
                    raise
            else:
                blocked = time.monotonic() - tried
                if blocked > BLOCKED_AFTER_S:  # held inside the transport (module notes)
                    if not waiting:
                        waiting = True
                        self.waits += 1
                    self._logger.warning(
                        f"{self.topic_name}: publication blocked {blocked:.1f} s in the "
                        "transport (a reader's process stopped or descheduled while it held "
                        "its shared-memory port)"
                    )
                break
            if not waiting:
                waiting = True
                self.waits += 1
            elif time.monotonic() >= warn_at:  # at 1 s, then every 5 s of one wait
                warn_at += WARN_PERIOD_S
                self._logger.warning(
                    f"{self.topic_name}: a reader has not taken the writer's last messages "
                    f"(every one is kept for it): publication waiting "
                    f"{time.monotonic() - start:.1f} s"
                )
        if waiting:
            self.waited_s += time.monotonic() - start


def publisher(node: Node, msg_type: type, name: str, qos: QoSProfile, lossless: bool):
    """
    A stream's publisher: :class:`WaitingPublisher` if ``lossless``, else rclpy's on ``qos``.

    Parameters
    ----------
    node, msg_type, name, qos
        As ``Node.create_publisher``.
    lossless : bool
        Keep every message until each reader has it, waiting when the history is full.
    """
    if lossless:
        return WaitingPublisher(node, msg_type, name, qos)
    return node.create_publisher(msg_type, name, qos)
