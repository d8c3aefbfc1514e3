"""A writer in a process of its own, started as the node executables start (for transport tests).

:func:`writer_script` is the Python source of such a process: the project's Fast DDS profile
(``amb_tools.transport_profile.use_project_profile``, with whatever ``AMB_TRANSPORT`` its
environment has), a node, a reliable ``std_msgs/String`` publisher, a wait of up to 60 s for a
reader to match, then the caller's ``body`` (which has ``pub``, ``node``, ``Duration``, ``String``,
``os``, ``sys`` and ``time`` at hand). Run it with ``python -c`` and read what it prints.
"""

from __future__ import annotations

import textwrap

__all__ = ["writer_script"]


def writer_script(node_name: str, topic: str, history: str, body: str) -> str:
    """
    Python source of a writer process.

    Parameters
    ----------
    node_name : str
        The writer node's name.
    topic : str
        The topic it publishes on.
    history : str
        The QoS's history, as ``QoSProfile`` keywords (``"depth=10"``,
        ``"depth=1, history=HistoryPolicy.KEEP_ALL"``).
    body : str
        What the process does once a reader matched (unindented source).
    """
    return f"""
import os, sys, time
from amb_tools.transport_profile import use_project_profile
use_project_profile()
import rclpy
from rclpy.duration import Duration
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("{node_name}")
qos = QoSProfile({history}, reliability=ReliabilityPolicy.RELIABLE)
pub = node.create_publisher(String, "{topic}", qos)
deadline = time.monotonic() + 60.0
while pub.get_subscription_count() < 1:
    if time.monotonic() > deadline:
        sys.exit("no reader matched in 60 s")
    time.sleep(0.01)
time.sleep(0.5)  # the reader's side of the match
{textwrap.dedent(body).strip()}
"""
