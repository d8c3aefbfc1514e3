"""
``wavelet_stack``: the filterbank, fault monitor, controller and recorder composed in one process.

The same nodes as ``wavelet_filterbank``, ``fault_monitor``, ``wavelet_controller`` and
``recorder`` (same names, parameters, topics, services and diagnostics; a params file's sections
for each apply unchanged), created in one process on one executor and sharing a
:class:`~amb_tools.local_bus.LocalBus`: the measurement stream is taken from DDS once for all,
and what a composed node publishes for the others (the filterbank's coefficients; the
controller's commands and statuses; the monitor's fault events, which the controller acts on)
goes to them in the publisher's call, while still being published on DDS for any outside reader
(the plant, another recorder). The recorder writes
from a thread of its own (:class:`~amb_tools.bag_writer.QueuedBagWriter`): the control path only
queues, and a slow disk does not stall it.
Each DDS take or publish from rclpy costs a fixed Python and middleware overhead per message
(``bench/dds_floor.py``), paid at the sample rate; composed, the node set pays it once per
message instead of once per reader (``bench/pipeline_profile.py --composed`` measures both).

The separate processes stay available (``amb-run`` and the launch file start either); each
part still runs alone. What composition gives up: a crash of one part's process takes the
others down with it, and they share one core's worth of Python (one GIL).

    ros2 run amb_wavelet_control wavelet_stack [--without NODE] \
        --ros-args --params-file config/amb_params.yaml
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from rclpy.utilities import remove_ros_args

from amb_apps.system import COMPOSED, PUBLISHERS
from amb_controller.node import WaveletControllerNode
from amb_fault_monitor.node import FaultMonitorNode
from amb_tools.local_bus import LocalBus
from amb_tools.node_main import run_nodes
from amb_tools.recorder_node import Recorder
from amb_wavelet.node import WaveletFilterbankNode

__all__ = ["FACTORIES", "main"]


#: Each composed node's class; created in the order of ``COMPOSED`` (the filterbank first: it
#: publishes the coefficients the others read, and it reads each measurement before they do;
#: the recorder last: it takes in process the streams already on the bus).
FACTORIES = {
    "wavelet_filterbank": WaveletFilterbankNode,
    "fault_monitor": FaultMonitorNode,
    "wavelet_controller": WaveletControllerNode,
    "recorder": Recorder,
}


def build_parser() -> argparse.ArgumentParser:
    """Command line (before ``--ros-args``)."""
    p = argparse.ArgumentParser(
        prog="wavelet_stack",
        description="The filterbank, fault monitor, controller and recorder in one process.",
    )
    p.add_argument(
        "--without",
        action="append",
        default=[],
        choices=["fault_monitor", "wavelet_controller", "recorder"],
        help="do not compose this node (repeatable)",
    )
    return p


def main(args: Sequence[str] | None = None) -> int:
    """Entry point of the ``wavelet_stack`` executable."""
    argv = list(sys.argv if args is None else args)
    own = build_parser().parse_args(remove_ros_args(argv)[1:])
    composed = [n for n in COMPOSED if n not in own.without]
    # what a composed node publishes reaches the others in process (no DDS reader of their own:
    # in lock-step one never got the stack's own messages until the stream stopped,
    # docs/history.md, "A composed lock-step run: the stack's own publications")
    bus = LocalBus(local_topics=tuple(t for t, node in PUBLISHERS.items() if node in composed))
    return run_nodes(
        [lambda cls=FACTORIES[n]: cls(bus) for n in composed],
        argv,
        process_name="wavelet_stack",
    )


if __name__ == "__main__":
    raise SystemExit(main())
