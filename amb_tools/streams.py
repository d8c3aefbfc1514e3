"""
How the parts' topics are carried: the QoS of the streams and the codes of the coefficient slots.

One home for what every node, the replay bridge, the tests and the benchmarks must agree on
(ARCHITECTURE.md, topics): the sample-rate streams (``/amb/measurement``,
``/amb/wavelet/coefficients``) are reliable and several control periods deep, because the
lock-step loop needs every sample; commands (``/amb/control/command``) are reliable, 16 deep;
the controller's status (``/amb/control/status``) is reliable and deep enough for a lost message
to be repaired (:data:`STATUS_QOS`).
A coefficient set names its frame and quadrature by the codes of ``CoefficientSet.msg``.
"""

from __future__ import annotations

from typing import Any

from amb_msgs.msg import CoefficientSet
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from amb_tools.lossless import WAITED_KEY, WaitingPublisher

__all__ = [
    "COMMAND_QOS",
    "FRAME_CODES",
    "MATCHED_KEY",
    "QUAD_CODES",
    "STATUS_QOS",
    "matched_subscribers",
    "stream_qos",
]

#: ``CoefficientSet.frame`` of each frame name of :mod:`amb_wavelet.frontend`.
FRAME_CODES = {"fixed": CoefficientSet.FRAME_FIXED, "rotating": CoefficientSet.FRAME_ROTATING}
#: ``CoefficientSet.quadrature`` of each quadrature name of :mod:`amb_wavelet.frontend`.
QUAD_CODES = {"even": CoefficientSet.QUADRATURE_EVEN, "odd": CoefficientSet.QUADRATURE_ODD}

#: ``/amb/control/command``: reliable, 16 commands deep (the plant keeps at most
#: ``delay_periods + 16`` periods ahead).
COMMAND_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=16, reliability=ReliabilityPolicy.RELIABLE
)

#: ``/amb/control/status`` (one message per control period): reliable, 256 deep. A message the
#: transport loses (a reader's shared-memory port full while its process is descheduled) is
#: resent only after the reader asks for it, at the writer's next heartbeat: every 3 s with
#: Fast DDS's defaults (30 periods at 10 periods/s, 201 at 67 Hz), every 20 ms with the nodes'
#: profile (:mod:`amb_tools.transport_profile`). A writer that kept fewer than the periods of
#: a 3 s wait (a bridge on the defaults) had already dropped it, and the recorder's bag missed
#: it for good (10 deep: 75 of 78 statuses in one loaded run, every command recorded).
STATUS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=256, reliability=ReliabilityPolicy.RELIABLE
)


def stream_qos(samples_per_period: int) -> QoSProfile:
    """
    QoS of the sample-rate streams: reliable, at least 8 control periods deep (1024 minimum).

    Parameters
    ----------
    samples_per_period : int
        Samples in one control period.

    Returns
    -------
    rclpy.qos.QoSProfile
        The lock-step loop needs every sample: none is dropped while a reader is slower. (In
        lock-step the writers make it KEEP_ALL: :mod:`amb_tools.lossless`.)
    """
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=max(1024, 8 * samples_per_period),
        reliability=ReliabilityPolicy.RELIABLE,
    )


#: Diagnostics key of a publisher's matched subscriptions: ``MATCHED_KEY + resolved topic``.
MATCHED_KEY = "subscribers "


def matched_subscribers(*publishers: Any) -> dict[str, int | float]:
    """
    Subscriptions each publisher has matched, keyed ``MATCHED_KEY + topic`` for diagnostics.

    The count is the writer's own (``rmw_publisher_count_matched_subscriptions``): a message
    published once a reader is counted here reaches it (reliable, kept in the writer's history
    until acknowledged). A count seen by any other participant (``count_subscribers``, the
    graph) does not say that: under load, discovery between two node processes was seen to
    take seconds, and everything published meanwhile was lost to the late reader. ``amb-run``
    waits on these counts before it starts the plant.

    Parameters
    ----------
    *publishers
        ``rclpy`` publishers, :class:`amb_tools.lossless.WaitingPublisher` (their wall time
        spent waiting for a slow reader as well, ``WAITED_KEY + topic``, s) or
        :class:`amb_tools.local_bus.StreamPublisher` (its DDS side).
    """
    out: dict[str, int | float] = {}
    for pub in publishers:
        dds = getattr(pub, "dds", pub)
        out[MATCHED_KEY + dds.topic_name] = dds.get_subscription_count()
        if isinstance(dds, WaitingPublisher):  # lockstep: how long a slow reader held it
            out[WAITED_KEY + dds.topic_name] = round(dds.waited_s, 3)
    return out
