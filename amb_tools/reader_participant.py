"""A DDS participant of a node's own for its stream readers, made when the transport stops feeding.

A node stopped for seconds (SIGSTOP, a starved process on a shared machine) can find its
stream readers fed no more, for good, while the writers run on (``docs/history.md``, "A reader
the transport stopped feeding"). Our reading of Fast DDS 2.14.5's shared-memory transport: the
writer's process marks the stopped listener's port as failed, and when the writer pushes before
the listener wakes, the two regenerate the port in an order that leaves the writer pushing into
a segment nobody listens to. A new reader of the same participant listens on the same port and
is not fed either (tried: 2d05ebb). A new participant has a new port, which the writer's process
opens afresh: :class:`ReaderParticipant` is one, in a context of its own in the same process,
spun by the node's executor, whose node takes the stream readers over
(:meth:`amb_tools.backlog.BacklogReader.move_to`). It is made only when a node finds its stream
silent while the stream's writer is still matched (``amb_controller.node``), so that a healthy
run never has it.

The new participant costs one discovery (its readers match the writers within tens of ms
idle); what the writers published between the stall and the match is not received (a gap the
readers' sequencers report as such). Every renewal makes a new participant and then closes the
one before it, so a participant id the writers may still hold a failed port for is not taken
again at once.
"""

from __future__ import annotations

import itertools

import rclpy
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

__all__ = ["ReaderParticipant"]

_numbers = itertools.count(1)


class ReaderParticipant:
    """A context, a participant and a node of their own, beside ``owner`` in its executor.

    Parameters
    ----------
    owner : rclpy.node.Node
        The node whose readers move here; must be spinning in an executor (it is added there).

    Attributes
    ----------
    node : rclpy.node.Node
        ``<owner>_readers_<k>`` in the owner's namespace and ROS domain, without parameter
        services or global arguments (its topics are the owner's resolved names).
    """

    def __init__(self, owner: Node) -> None:
        executor = owner.executor
        if executor is None:
            raise RuntimeError(f"node {owner.get_name()} is not in an executor")
        self.context = rclpy.Context()
        # no signal handlers: the process's own (amb_tools.node_main.run_nodes) stay in charge
        rclpy.init(
            context=self.context,
            domain_id=owner.context.get_domain_id(),
            signal_handler_options=SignalHandlerOptions.NO,
        )
        self.node = rclpy.create_node(
            f"{owner.get_name()}_readers_{next(_numbers)}",
            namespace=owner.get_namespace(),
            context=self.context,
            use_global_arguments=False,
            start_parameter_services=False,
        )
        self._executor = executor
        executor.add_node(self.node)

    def close(self) -> None:
        """Take the node out of the executor, destroy it and shut the context down."""
        self._executor.remove_node(self.node)
        self.node.destroy_node()
        self.context.try_shutdown()
