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
silent for ``reader_renewal_after`` s while the stream's writer is still matched and the
readers' queues hold nothing (:class:`DeafReaders`), so that a healthy run never has it.

The new participant costs one discovery (its readers match the writers within tens of ms
idle); what the writers published between the stall and the match is not received (a gap the
readers' sequencers report as such). Every renewal makes a new participant and then closes the
one before it, so a participant id the writers may still hold a failed port for is not taken
again at once.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Sequence
from typing import Any, Protocol

import rclpy
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from amb_tools.node_main import descriptor

__all__ = [
    "RENEWAL_AFTER",
    "ClosesReaderParticipant",
    "DeafReaders",
    "MovableSubscription",
    "ReaderParticipant",
    "Readers",
    "StreamReader",
    "declare_reader_renewal",
    "watch_readers",
]

#: Parameter: s of silence, with the writer matched, before the readers move (0 = never).
RENEWAL_AFTER = "reader_renewal_after"

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


def declare_reader_renewal(node: Node) -> float:
    """Declare ``reader_renewal_after`` on ``node`` (read-only); return it, s."""
    node.declare_parameter(
        RENEWAL_AFTER,
        4.0,
        descriptor(
            "s without a message on the node's watched stream (the measurements; the plant's: "
            "the commands) while its writer is still matched and nothing is queued, before the "
            "stream readers move to a DDS participant of their own (the transport stopped "
            "feeding them; 0 = never)",
            floats=(0.0, 3600.0),
        ),
    )
    return float(node.get_parameter(RENEWAL_AFTER).value)


class StreamReader(Protocol):
    """What :class:`DeafReaders` needs of a reader: its subscription, a poll and a move."""

    subscription: Any

    def poll(self) -> object:
        """Deliver, in order, every message queued now."""

    def move_to(self, node: Node) -> None:
        """Subscribe the same topic from ``node``; destroy the subscription held until then."""


#: A node's readers: fixed, or a callable returning the current ones (a recorder's grow).
Readers = Sequence[StreamReader | None] | Callable[[], Sequence[StreamReader | None]]


class MovableSubscription:
    """An ordinary (deserialising) subscription that :class:`DeafReaders` can move.

    What :class:`amb_tools.backlog.BacklogReader` offers for the raw streams, for a node's
    low-rate reader (the plant's commands): ``poll`` delivers what is queued now, ``move_to``
    subscribes the same topic from another node and destroys the subscription held until then.
    """

    def __init__(
        self, node: Node, msg_type: type, name: str, callback: Callable[[object], None], qos
    ) -> None:
        self._node = node
        self._msg_type = msg_type
        self._callback = callback
        self._qos = qos
        self.subscription = node.create_subscription(msg_type, name, callback, qos)

    def poll(self) -> None:
        """Deliver, in order, every message queued now."""
        taken = []
        with self.subscription.handle:
            while (
                item := self.subscription.handle.take_message(self._msg_type, False)
            ) is not None:
                taken.append(item[0])
        for msg in taken:
            self._callback(msg)

    def move_to(self, node: Node) -> None:
        """Subscribe the same (resolved) topic from ``node``; destroy the old subscription."""
        topic = self.subscription.topic_name
        self._node.destroy_subscription(self.subscription)
        self._node = node
        self.subscription = node.create_subscription(
            self._msg_type, topic, self._callback, self._qos
        )


class DeafReaders:
    """Watches a node's stream readers and moves them to a new participant when they go deaf.

    Deaf: the first reader's stream (the measurements; the plant's commands) has brought nothing
    for ``after`` s, its writer is still matched, and the readers' queues, emptied first, held
    nothing (a process let go after a stop has its backlog there). Once per silence: a new
    renewal needs a message first. A writer that merely paused costs one participant (module
    docstring).

    Parameters
    ----------
    node : rclpy.node.Node
        The readers' node; must be spinning in an executor when a renewal happens.
    readers : sequence of StreamReader or None, or a callable returning one
        The node's DDS stream readers, the watched one first (None entries are skipped; none at
        all: nothing is watched, ``renewals`` stays 0). A callable is asked at each check (a
        recorder subscribes topics as they appear; it returns nothing while the watched stream
        has no reader); a reader made after a renewal belongs on :attr:`readers_node`.
    progress : callable
        Returns a value that changes whenever a message of the watched stream arrived (a count,
        a wall time).
    after : float
        s of silence before a renewal; 0: never (no timer is made).
    period : float
        s between checks.

    Attributes
    ----------
    renewals : int
        Renewals so far (``readers_renewed`` on the node's ``/diagnostics``).
    """

    def __init__(
        self,
        node: Node,
        readers: Readers,
        progress: Callable[[], object],
        after: float,
        period: float = 0.25,
    ) -> None:
        self._node = node
        self._readers_of = readers if callable(readers) else (lambda fixed=tuple(readers): fixed)
        self._progress = progress
        self.after = after
        self.renewals = 0
        self._seen = progress()
        self._seen_at = time.monotonic()
        self._heard = False  # a message since the start or the last renewal
        self._participant: ReaderParticipant | None = None
        if after > 0 and (callable(readers) or self._readers()):
            node.create_timer(period, self.check)

    def _readers(self) -> list[StreamReader]:
        return [r for r in self._readers_of() if r is not None]

    @property
    def readers_node(self) -> Node:
        """The node the stream readers are on now: the owner's, or the newest participant's."""
        return self._node if self._participant is None else self._participant.node

    def check(self) -> str | None:
        """Move the readers if they are deaf; return what was logged then, else None."""
        now = time.monotonic()
        value = self._progress()
        if value != self._seen:
            self._seen, self._seen_at, self._heard = value, now, True
            return None
        if not self._heard or now - self._seen_at <= self.after:
            return None
        readers = self._readers()
        if not readers or readers[0].subscription.get_publisher_count() == 0:
            return None  # no writer: a silent stream, not a deaf reader
        for reader in readers:
            reader.poll()
        if self._progress() != self._seen:
            return None  # the queue had messages after all (taken now)
        fresh = ReaderParticipant(self._node)
        for reader in readers:
            reader.move_to(fresh.node)
        old, self._participant = self._participant, fresh
        if old is not None:
            old.close()
        self.renewals += 1
        self._heard = False
        topic = readers[0].subscription.topic_name
        text = (
            f"nothing on {topic} for {now - self._seen_at:.2f} s while its writer is still "
            f"matched: the stream readers moved to a new participant ({fresh.node.get_name()}; "
            'docs/history.md, "A reader the transport stopped feeding")'
        )
        self._node.get_logger().warning(text)
        return text

    def close(self) -> None:
        """Close the readers' own participant, if one was made."""
        if self._participant is not None:
            self._participant.close()
            self._participant = None


class ClosesReaderParticipant:
    """Mixin of a node that watches its readers (``self._deaf = watch_readers(...)``).

    ``destroy_node`` closes the readers' own participant, if one was made, then the node.
    ``_deaf`` stays None for a node whose configuration failed before it was made. List it
    before ``Node``: ``class FilterbankNode(ClosesReaderParticipant, Node)``.
    """

    _deaf: DeafReaders | None = None

    def destroy_node(self) -> None:
        """Close the readers' own participant, if one was made, then the node."""
        if self._deaf is not None:
            self._deaf.close()
        super().destroy_node()


def watch_readers(node: Node, readers: Readers, progress: Callable[[], object]) -> DeafReaders:
    """Declare ``reader_renewal_after`` on ``node`` and watch ``readers`` with it.

    ``readers`` empty for a composed node whose streams come in process or through the reader
    the stack shares (the filterbank, which holds that reader, watches it): the parameter is
    declared all the same, nothing is watched.
    """
    return DeafReaders(node, readers, progress, declare_reader_renewal(node))
