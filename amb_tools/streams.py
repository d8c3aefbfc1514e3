"""
How the parts' topics are carried: the QoS of the streams and the codes of the coefficient slots.

One home for what every node, the replay bridge, the tests and the benchmarks must agree on
(ARCHITECTURE.md, topics): the sample-rate streams (``/amb/measurement``,
``/amb/wavelet/coefficients``) are reliable and several control periods deep, because the
lock-step loop needs every sample; commands (``/amb/control/command``) are reliable, 16 deep.
A coefficient set names its frame and quadrature by the codes of ``CoefficientSet.msg``.
"""

from __future__ import annotations

from amb_msgs.msg import CoefficientSet
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ["COMMAND_QOS", "FRAME_CODES", "QUAD_CODES", "stream_qos"]

#: ``CoefficientSet.frame`` of each frame name of :mod:`amb_wavelet.frontend`.
FRAME_CODES = {"fixed": CoefficientSet.FRAME_FIXED, "rotating": CoefficientSet.FRAME_ROTATING}
#: ``CoefficientSet.quadrature`` of each quadrature name of :mod:`amb_wavelet.frontend`.
QUAD_CODES = {"even": CoefficientSet.QUADRATURE_EVEN, "odd": CoefficientSet.QUADRATURE_ODD}

#: ``/amb/control/command``: reliable, 16 commands deep (the plant keeps at most
#: ``delay_periods + 16`` periods ahead).
COMMAND_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=16, reliability=ReliabilityPolicy.RELIABLE
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
        The lock-step loop needs every sample: none is dropped while a reader is slower.
    """
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=max(1024, 8 * samples_per_period),
        reliability=ReliabilityPolicy.RELIABLE,
    )
