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
(:meth:`amb_tools.backlog.BacklogReader.subscribe_on`). It is made only when a node finds its
stream silent for ``reader_renewal_after`` s while the stream's writer is still matched and the
readers' queues hold nothing (:class:`DeafReaders`), so that a healthy run never has it.

The move is made before the old readers are broken. The new participant's readers are made
beside the old ones and left unspun; once the watched one has matched its writer, and every
other one whose old reader was fed meanwhile holds a message too (its writer sends to it: a
stream that runs on through the move, :meth:`MovableReader.ready`), the old
readers are drained once more, destroyed, and the new ones take over from their queues, minus
the messages the old ones delivered last (the overlap, and what a writer resends from its
history to a reader it newly matched). If the old watched reader delivers a message
first, the stream was only paused (a writer held, not a deaf port) and the move is called off
(``docs/history.md``, "A reader move made before the old readers are broken"). The new
participant costs one discovery (its readers match the writers within tens of ms idle); in a
real deafness what the writers published between the stall and the match is not received (a gap
the readers' sequencers report as such). Every renewal makes a new participant and then closes
the one before it, so a participant id the writers may still hold a failed port for is not taken
again at once.
"""

from __future__ import annotations

import itertools
import time
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple, Protocol

import rclpy
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from amb_tools.node_main import descriptor

__all__ = [
    "MATCH_WAIT",
    "RECENT_MESSAGES",
    "RENEWAL_AFTER",
    "ClosesReaderParticipant",
    "DeafReaders",
    "MovableReader",
    "MovableSubscription",
    "PendingMove",
    "ReaderParticipant",
    "Readers",
    "StreamReader",
    "declare_reader_renewal",
    "has_queued",
    "take_queued",
    "watch_readers",
]

#: Messages a movable reader remembers having delivered (its newest), to be skipped from its
#: successor's first deliveries after a switch: the overlap of the two, and what a writer
#: resends to a newly matched reader from its history (seen: a command writer's 16 in a loaded
#: suite). A stream's history is at most 1024 messages deep. A new message byte for byte equal
#: to one of these would be dropped too; the streams' messages carry their sample index or
#: stamp.
RECENT_MESSAGES = 4096

#: s a move waits at least, once the watched successor has matched, for the others to match
#: their writers (:meth:`MovableReader.ready`) before it switches over all the same.
MATCH_WAIT = 1.0

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
        services or global arguments (its topics are the owner's resolved names). Not spun
        until :meth:`start`: its subscriptions queue what they receive.
    """

    def __init__(self, owner: Node) -> None:
        executor = owner.executor
        if executor is None:
            raise RuntimeError(f"node {owner.get_name()} is not in an executor")
        self._started = False
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

    def start(self) -> None:
        """Add the node to the owner's executor: its callbacks are called from now on."""
        if not self._started:
            self._executor.add_node(self.node)
            self._started = True

    def close(self) -> None:
        """Take the node out of the executor, destroy it and shut the context down."""
        if self._started:
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
    """What :class:`DeafReaders` needs of a reader: its subscription, a poll and a move.

    A move has two steps: :meth:`subscribe_on` makes the successor beside the subscription,
    then :meth:`switch` hands over to it, or :meth:`cancel` drops it.
    """

    subscription: Any

    def poll(self) -> object:
        """Deliver, in order, every message queued now."""

    def subscribe_on(self, node: Node) -> Any:
        """Subscribe the same topic from ``node`` (not spun yet) as the pending successor.

        Returns the new subscription. Until :meth:`switch` or :meth:`cancel` the reader
        remembers what it delivers.
        """

    def ready(self) -> bool:
        """The pending successor can take over without a gap (:meth:`MovableReader.ready`)."""

    def switch(self) -> None:
        """Drain and destroy the subscription; deliver the successor's queue less what was seen."""

    def cancel(self) -> None:
        """Destroy the pending successor; the subscription stays."""


class PendingMove:
    """A reader's pending successor.

    The part of a two-step move (:class:`StreamReader`) that every reader shares: the new
    subscription and its node, and how many messages the old one had delivered when the
    successor was made.
    """

    def __init__(self, node: Node, subscription: Any, delivered: int = 0) -> None:
        self.node = node
        self.subscription = subscription
        self.delivered = delivered


def has_queued(subscription: Any, context: rclpy.Context) -> bool:
    """Whether ``subscription`` (of a node in ``context``) holds a message now; none is taken.

    A wait set of the one subscription, waited on for no time: what rclpy's executors ask
    before they take (``Executor._wait_for_ready_callbacks``), for a subscription no executor
    spins.
    """
    with context.handle, subscription.handle:
        wait_set = _rclpy.WaitSet(1, 0, 0, 0, 0, 0, context.handle)
        wait_set.clear_entities()
        wait_set.add_subscription(subscription.handle)
        wait_set.wait(0)
        return subscription.handle.pointer in wait_set.get_ready_entities("subscription")


def take_queued(subscription: Any, msg_type: type, raw: bool) -> list[tuple[Any, dict]]:
    """Take every message queued on ``subscription`` now, as rclpy's executors take them.

    Returns
    -------
    list of (message, info)
        The message (CDR bytes if ``raw``, else deserialised) and its message info, oldest
        first.
    """
    taken = []
    with subscription.handle:
        while (item := subscription.handle.take_message(msg_type, raw)) is not None:
            taken.append(item)
    return taken


class MovableReader:
    """The two-step move of :class:`StreamReader` for a reader holding ``subscription``.

    A subclass sets ``_node`` and ``subscription``, says how to subscribe the same topic from
    another node (:meth:`_subscribe`), and on each of its delivery paths (its ``poll`` and its
    callback) delivers only the messages from :meth:`_fresh_from` on and passes those to
    :meth:`_seen`. After a switch the successor's first messages are the ones the old reader
    delivered too (its queue, and what was still on its way to it when the old one was drained
    for the last time): :meth:`_fresh_from` drops them, up to the first the old one did not
    deliver.
    """

    _node: Node
    subscription: Any
    _move: PendingMove | None = None
    _recent: deque | None = None
    _delivered: int = 0  # messages delivered so far
    _catching_up: Any = None  # after a switch: the old reader's last deliveries, for ``in``
    #: Messages remembered (a subclass holding large deserialised messages keeps fewer).
    recent_size: int = RECENT_MESSAGES

    def poll(self) -> object:
        """Deliver, in order, every message queued now."""
        raise NotImplementedError

    def _subscribe(self, node: Node) -> Any:
        """The same topic, QoS and callback, subscribed from ``node``."""
        raise NotImplementedError

    def _record(self) -> deque:
        """The newest :attr:`recent_size` messages delivered (made at the first use)."""
        if self._recent is None:
            self._recent = deque(maxlen=self.recent_size)
        return self._recent

    def _fresh_from(self, items: Sequence) -> int:
        """Index of the first of ``items`` (next to be delivered, in order) to deliver.

        0 but after a switch, while the successor delivers what the old reader delivered: those
        are skipped, up to the first the old one did not deliver, from which on all are new.
        """
        lookup = self._catching_up
        if lookup is None:
            return 0
        for k, item in enumerate(items):
            if item not in lookup:
                self._catching_up = None
                return k
        return len(items)

    def _seen(self, items: Sequence) -> None:
        """Remember ``items`` as delivered."""
        self._record().extend(items)
        self._delivered += len(items)

    def _lookup(self) -> Any:
        """The newest messages delivered, for ``in`` (a set where they are hashable).

        CDR bytes, or deserialised messages: any values with ``==``.
        """
        try:
            return set(self._record())
        except TypeError:  # deserialised messages are not hashable
            return list(self._record())

    def subscribe_on(self, node: Node) -> Any:
        """Subscribe the same topic from ``node`` as the pending successor; return it."""
        self.cancel()
        new = self._subscribe(node)
        self._move = PendingMove(node, new, self._delivered)
        return new

    def ready(self) -> bool:
        """The pending successor can take over without a gap (True without one).

        It has matched as many writers as the subscription, and, if the subscription delivered
        a message since the successor was made, the successor holds one too. The second is the
        writers' side of the match, which a reader's publisher count does not show: a writer
        sends to a reader only once it has matched it in turn, and what it sends before then
        reaches the old reader alone. Switched over in between, a stream that runs on through
        the move (a recorder's commands, while its measurements pause) lost the messages of
        the gap (one command of 188 in a loaded suite, stop 58's CI). Asked a while after the
        successor was made (:class:`DeafReaders`: a check period later), so that a stream that
        runs on has delivered meanwhile; a stream silent that long is switched over once
        matched.
        """
        move = self._move
        if move is None:
            return True
        if move.subscription.get_publisher_count() < self.subscription.get_publisher_count():
            return False
        if self._delivered == move.delivered:
            return True  # nothing since the successor was made: nothing it could have missed
        return has_queued(move.subscription, move.node.context)

    def switch(self) -> None:
        """Drain and destroy the subscription; go on from the successor, less what was seen.

        Every message the successor delivers from then on that the old reader delivered is
        skipped (:meth:`_fresh_from`), up to the first it did not.
        """
        move = self._move
        if move is None:
            return
        self.poll()
        self._node.destroy_subscription(self.subscription)
        self._node, self.subscription, self._move = move.node, move.subscription, None
        self._catching_up = self._lookup()
        self.poll()

    def cancel(self) -> None:
        """Destroy the pending successor, if any."""
        if self._move is not None:
            self._move.node.destroy_subscription(self._move.subscription)
            self._move = None


#: A node's readers: fixed, or a callable returning the current ones (a recorder's grow).
Readers = Sequence[StreamReader | None] | Callable[[], Sequence[StreamReader | None]]


class MovableSubscription(MovableReader):
    """An ordinary (deserialising) subscription that :class:`DeafReaders` can move.

    What :class:`amb_tools.backlog.BacklogReader` offers for the raw streams, for a node's
    low-rate reader (the plant's commands): ``poll`` delivers what is queued now;
    ``subscribe_on``, ``switch`` and ``cancel`` move it to another node (:class:`MovableReader`).
    """

    #: the plant's commands: a writer keeps 16 (``COMMAND_QOS``); each holds its force samples
    recent_size = 256

    def __init__(
        self, node: Node, msg_type: type, name: str, callback: Callable[[object], None], qos
    ) -> None:
        self._node = node
        self._msg_type = msg_type
        self._callback = callback
        self._qos = qos
        self.subscription = node.create_subscription(msg_type, name, self._deliver, qos)

    def _deliver(self, msg: object) -> None:
        if self._fresh_from((msg,)):
            return  # delivered by the reader this one succeeded
        self._seen((msg,))
        self._callback(msg)

    def _take(self) -> list:
        return [msg for msg, _info in take_queued(self.subscription, self._msg_type, False)]

    def poll(self) -> None:
        """Deliver, in order, every message queued now."""
        for msg in self._take():
            self._deliver(msg)

    def _subscribe(self, node: Node) -> Any:
        return node.create_subscription(
            self._msg_type, self.subscription.topic_name, self._deliver, self._qos
        )


class _Move(NamedTuple):
    """A move under way: the new participant, the readers given a successor there, since when."""

    participant: ReaderParticipant
    readers: list[StreamReader]
    successor: Any  # the watched reader's new subscription
    silent_for: float  # s of silence that began it
    began: float  # time.monotonic() when it began


class DeafReaders:
    """Watches a node's stream readers and moves them to a new participant when they go deaf.

    Deaf: the first reader's stream (the measurements; the plant's commands) has brought nothing
    for ``after`` s, its writer is still matched, and the readers' queues, emptied first, held
    nothing (a process let go after a stop has its backlog there). Once per silence: a new
    renewal needs a message first. The move is made before the old readers are broken (module
    docstring): each reader gets a successor on a new, unspun participant; once the watched
    successor has matched its writer and the others are ready (:meth:`MovableReader.ready`;
    at most ``max(after, MATCH_WAIT)`` s after the move began), the readers switch over and the
    participant is spun. A
    message on the old watched reader before that calls the move off: the writer had only
    paused.

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
        Moves completed so far (``readers_renewed`` on the node's ``/diagnostics``).
    called_off : int
        Moves called off because the old watched reader got a message first.
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
        self.renewals = self.called_off = 0
        self._seen = progress()
        self._seen_at = time.monotonic()
        self._heard = False  # a message since the start or the last renewal
        self._participant: ReaderParticipant | None = None
        self._move: _Move | None = None
        if after > 0 and (callable(readers) or self._readers()):
            node.create_timer(period, self.check)

    def _readers(self) -> list[StreamReader]:
        return [r for r in self._readers_of() if r is not None]

    @property
    def readers_node(self) -> Node:
        """The node the stream readers are on now: the owner's, or the newest participant's."""
        return self._node if self._participant is None else self._participant.node

    @property
    def moving(self) -> bool:
        """A move is under way (successors made, not yet switched to)."""
        return self._move is not None

    def check(self) -> str | None:
        """Begin, complete or call off a move; return what was logged at a warning, else None."""
        now = time.monotonic()
        value = self._progress()
        if self._move is not None:
            return self._advance(now, value)
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
        successors = [reader.subscribe_on(fresh.node) for reader in readers]
        self._move = _Move(fresh, readers, successors[0], now - self._seen_at, now)
        self._node.get_logger().info(
            f"nothing on {readers[0].subscription.topic_name} for {now - self._seen_at:.2f} s "
            f"while its writer is still matched: readers made on a new participant "
            f"({fresh.node.get_name()}), to take over once they match"
        )
        return None

    def _advance(self, now: float, value: object) -> str | None:
        move = self._move
        assert move is not None
        watched = move.readers[0]
        if value == self._seen:
            if watched.subscription.get_publisher_count() == 0:
                return self._call_off(move, "its writer is gone")
            if move.successor.get_publisher_count() == 0:
                return None  # the successor has not matched its writer yet
            for reader in move.readers:  # what the old readers hold, delivered before the switch
                reader.poll()
            value = self._progress()
        if value != self._seen:
            self._seen, self._seen_at, self._heard = value, now, True
            return self._call_off(move, "its reader got a message: the writer had paused")
        waiting = [r.subscription.topic_name for r in move.readers if not r.ready()]
        if waiting:
            if now - move.began < max(self.after, MATCH_WAIT):
                return None  # a stream running on through the move: not yet sent to its successor
            self._node.get_logger().warning(
                f"readers moving to {move.participant.node.get_name()}: the successors of "
                f"{waiting} have not matched their writers in {now - move.began:.2f} s; "
                "switched over all the same (what those writers sent meanwhile is lost)"
            )
        late = [r for r in self._readers() if r not in move.readers]  # subscribed meanwhile
        for reader in late:
            reader.subscribe_on(move.participant.node)
        for reader in [*move.readers, *late]:
            reader.switch()
        move.participant.start()
        old, self._participant, self._move = self._participant, move.participant, None
        if old is not None:
            old.close()
        self.renewals += 1
        self._heard = False
        topic = watched.subscription.topic_name
        text = (
            f"nothing on {topic} for {move.silent_for:.2f} s while its writer is still "
            f"matched: the stream readers moved to a new participant "
            f'({self.readers_node.get_name()}; docs/history.md, "A reader the transport '
            'stopped feeding")'
        )
        self._node.get_logger().warning(text)
        return text

    def _call_off(self, move: _Move, why: str) -> None:
        text = (
            f"move of the readers of {move.readers[0].subscription.topic_name} to "
            f"{move.participant.node.get_name()} called off: {why}"
        )
        for reader in move.readers:
            reader.cancel()
        move.participant.close()
        self._move = None
        self.called_off += 1
        self._node.get_logger().info(text)

    def close(self) -> None:
        """Close the readers' own participant and a pending one, if made."""
        if self._move is not None:
            for reader in self._move.readers:
                reader.cancel()
            self._move.participant.close()
            self._move = None
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
