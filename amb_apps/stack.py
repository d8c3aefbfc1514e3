"""
``wavelet_stack``: the filterbank, the fault monitor and the controller composed in one process.

The same three nodes as ``wavelet_filterbank``, ``fault_monitor`` and ``wavelet_controller``
(same names, parameters, topics, services and diagnostics; a params file's sections for each
apply unchanged), created in one process on one executor and sharing a
:class:`~amb_tools.local_bus.LocalBus`: the measurement stream is taken from DDS once for the
three, and the filterbank's coefficients go to the controller and the monitor in the
publisher's call, while still being published on DDS for the recorder and any outside reader.
Each DDS take or publish from rclpy costs a fixed Python and middleware overhead per message
(``bench/dds_floor.py``), paid at the sample rate; composed, the node set pays it once per
message instead of once per reader (``bench/pipeline_profile.py --composed`` measures both).

The separate processes stay available (``amb-run`` and the launch file start either); each
part still runs alone. What composition gives up: a crash of one part's process takes the
three down together, and the three share one core's worth of Python (one GIL).

    ros2 run amb_wavelet_control wavelet_stack --ros-args --params-file config/amb_params.yaml
"""

from __future__ import annotations

from collections.abc import Sequence

from amb_common import topics
from amb_controller.node import WaveletControllerNode
from amb_fault_monitor.node import FaultMonitorNode
from amb_tools.local_bus import LocalBus
from amb_tools.node_main import run_nodes
from amb_wavelet.node import WaveletFilterbankNode

__all__ = ["COMPOSED", "main"]

#: The nodes the stack composes, in creation order (the filterbank first: it publishes the
#: coefficients the others read, and it reads each measurement before they do).
COMPOSED = ("wavelet_filterbank", "fault_monitor", "wavelet_controller")


def main(args: Sequence[str] | None = None) -> int:
    """Entry point of the ``wavelet_stack`` executable."""
    bus = LocalBus(local_topics=(topics.COEFFICIENTS,))
    return run_nodes(
        [
            lambda: WaveletFilterbankNode(bus),
            lambda: FaultMonitorNode(bus),
            lambda: WaveletControllerNode(bus),
        ],
        args,
        process_name="wavelet_stack",
    )


if __name__ == "__main__":
    raise SystemExit(main())
