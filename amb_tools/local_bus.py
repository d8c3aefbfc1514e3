"""
In-process hand-off of the sample-rate streams between nodes composed in one process.

rclpy has no intra-process path (rclcpp's ``use_intra_process_comms``): two rclpy nodes in one
process still exchange every message through DDS, paying a publish and one take per reader.
At 67 Hz x 32 the measurement stream alone is 2144 messages per second to the filterbank, the
controller and the fault monitor. A :class:`LocalBus` shared by nodes created in one process
(``wavelet_stack``, :mod:`amb_apps.stack`) carries the streams as raw CDR bytes:

- a topic published by one of the composed nodes (the filterbank's coefficients) is still
  published on DDS for every outside reader (a recorder or tool in another process, another
  host) and handed, in the publisher's call, to the composed readers, which create no DDS
  reader of their own;
- a topic published outside (the plant's or the bridge's measurements) is taken from DDS by one
  raw reader for the whole process, and each message is handed to every composed reader.

Readers get the same bytes a ``raw=True`` subscription gives, in the order DDS delivered them;
each stays keyed on its sample indices, so a composed system computes what separate processes
compute (lock-step results are bit-identical; ``test/system``). Nodes take ``bus=None`` when
run alone and then subscribe and publish as usual (:func:`stream_subscription`,
:func:`stream_publisher`).

The control path first, in lock-step. One thread serves every composed node, and in lock-step
the plant waits for each command: a reader subscribed ``urgent`` (the filterbank's
measurements, the controller's measurements and coefficients) is handed each message at once;
the others (the fault monitor, the recorder) get theirs, in the same order, once every message
the process's DDS reader found queued at that wake (the plant's burst of a period) has gone
through the urgent ones, so that the command leaves and the plant computes its next period on
the other core while the monitor and the recorder work. Each reader still sees its streams in
their order, and the relative order of the deferred readers' messages is kept (a coefficient
message the filterbank publishes for a sample reaches the monitor before that sample's
measurement, as before). In realtime (a reader with a catch-up bound) a wake normally brings one
sample, and every reader is served at each message, urgent ones first: deferring each message
made the periods controlled at 67 Hz x 32 worse, not better (``docs/history.md``, "The control
path first"). A realtime wake that finds several samples queued (the stack is behind: a stall,
a fault-monitor episode) defers as lock-step does, so that the command of a period leaves as
soon as the controller has its last coefficient, not after the monitor's and the recorder's work
on the whole backlog (``docs/history.md``, "Late commands at 67 Hz x 32 over 60 s").

The deferred work is done in slices. In lock-step the plant answers each command at once, so
the flush's polls always find the next period queued and its work never runs dry while the plant
runs: as one callback, it kept the executor from everything else in the process until the run
ended (timers, parameter services, DDS readers). After
:data:`FLUSH_SLICE` of work a flush returns, and a task on the executor resumes it once the
executor has served what else is ready (a task, not a timer: rclpy's ``EventsExecutor`` ran
other due timers several times per period when a timer was reset that often); the urgent
readers are still served at every wake and poll. With the ``EventsExecutor`` the process's
timers still wait until a lock-step stream stops (``docs/history.md``, "A composed lock-step
run"): what the composed nodes publish for each other goes through the bus, not DDS.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

from rclpy.node import Node
from rclpy.qos import QoSProfile

from amb_tools.backlog import NO_CATCH_UP, BacklogReader, CatchUp
from amb_tools.lossless import publisher as lossless_publisher

__all__ = ["LocalBus", "StreamPublisher", "stream_publisher", "stream_subscription"]

RawCallback = Callable[[bytes], None]

#: s of deferred work between two polls of the DDS readers (:meth:`LocalBus.flush`): at
#: 67 Hz x 32 a sample comes every 0.47 ms.
POLL_PERIOD = 0.0005
#: s of deferred work after which :meth:`LocalBus.flush` gives the executor a turn and resumes
#: from a task: the process's other callbacks wait at most this long (module notes).
FLUSH_SLICE = 0.005


@dataclass
class _Topic:
    """The composed readers of one resolved topic name and how its messages arrive."""

    msg_type: type
    urgent: list[RawCallback] = field(default_factory=list)  # handed each message at once
    deferred: list[RawCallback] = field(default_factory=list)  # after the wake's urgent ones
    lossless: list[RawCallback] = field(default_factory=list)  # also get what a catch-up drops
    local: bool = False  # published by a composed node (else: one DDS reader feeds the readers)
    dds_reader: BacklogReader | None = None


class LocalBus:
    """
    The streams shared by the nodes of one process.

    Parameters
    ----------
    local_topics : iterable of str
        Names (relative or absolute, resolved against each node's namespace) published by a
        composed node. Readers of these get the publisher's bytes directly; declare them before
        the readers subscribe, so that none opens a DDS reader for them.
    """

    def __init__(self, local_topics: tuple[str, ...] = ()) -> None:
        self._local_names = tuple(local_topics)
        self._topics: dict[str, _Topic] = {}
        # deferred deliveries: (reader, bytes, the DDS reader the bytes came from, its gap flag)
        self._pending: deque[tuple[RawCallback, bytes, BacklogReader | None, bool]] = deque()
        self._in_wake = False  # a DDS reader's wake is delivering: defer until its end
        self._flushing = False
        self._resume_node: Node | None = None  # its executor resumes a flush stopped at its slice
        self._resume_due = False  # a task to resume is on that executor

    def _declared_local(self, node: Node, resolved: str) -> bool:
        """Whether ``resolved`` is one of the local topics (their names resolved by ``node``)."""
        return any(node.resolve_topic_name(n) == resolved for n in self._local_names)

    def _topic(self, node: Node, msg_type: type, name: str) -> tuple[str, _Topic]:
        resolved = node.resolve_topic_name(name)
        topic = self._topics.get(resolved)
        if topic is None:
            local = self._declared_local(node, resolved)
            topic = self._topics[resolved] = _Topic(msg_type, local=local)
        elif topic.msg_type is not msg_type:
            raise TypeError(
                f"{resolved}: {msg_type.__name__} requested, the bus carries "
                f"{topic.msg_type.__name__}"
            )
        return resolved, topic

    def subscribe(
        self,
        node: Node,
        msg_type: type,
        name: str,
        callback: RawCallback,
        qos: QoSProfile,
        catch_up: CatchUp = NO_CATCH_UP,
        lossless: bool = False,
        urgent: bool = False,
    ) -> BacklogReader | None:
        """
        Hand every message of topic ``name`` (CDR bytes) to ``callback``.

        Parameters
        ----------
        node : rclpy.node.Node
            The reading node (its namespace resolves ``name``; for a topic published outside,
            the first reader's node holds the process's one DDS reader).
        msg_type : type
            The message class.
        name : str
            Topic name.
        callback : callable
            Called with the raw CDR of each message.
        qos : rclpy.qos.QoSProfile
            QoS of the DDS reader (outside topics), as the node would have used alone.
        catch_up : amb_tools.backlog.CatchUp
            The DDS reader's catch-up bound (:class:`amb_tools.backlog.BacklogReader`); the
            first reader of a topic sets it for all.
        lossless : bool
            Also hand over, in order, the messages the shared DDS reader drops to catch up
            (the composed recorder: every sample in the bag while the control nodes skip).
        urgent : bool
            The reader is on the control path: it is handed each message at once, the others
            after the wake's urgent deliveries (module notes).

        Returns
        -------
        BacklogReader or None
            The process's DDS reader of an outside topic (shared); None for a local topic.
        """
        resolved, topic = self._topic(node, msg_type, name)
        (topic.urgent if urgent else topic.deferred).append(callback)
        if lossless:
            topic.lossless.append(callback)
        if not topic.local and topic.dds_reader is None:
            if self._resume_node is None:  # deferred work comes only from DDS readers' wakes
                self._resume_node = node
            topic.dds_reader = BacklogReader(
                node, msg_type, resolved, lambda raw, t=topic: self._wake_deliver(t, raw), qos,
                catch_up, lambda raw, t=topic: self._deliver_dropped(t, raw), self._end_wake,
            )  # fmt: skip
        return topic.dds_reader

    def carries(self, node: Node, name: str) -> bool:
        """Whether topic ``name`` (resolved against ``node``) is on the bus already."""
        resolved = node.resolve_topic_name(name)
        return resolved in self._topics or self._declared_local(node, resolved)

    def publisher(
        self, node: Node, msg_type: type, name: str, qos: QoSProfile, lossless: bool = False
    ) -> StreamPublisher:
        """A publisher of ``name`` that also hands each message to the composed readers.

        ``lossless``: its DDS side waits for a slow outside reader (:mod:`amb_tools.lossless`).
        """
        resolved, topic = self._topic(node, msg_type, name)
        if not topic.local:
            raise ValueError(
                f"{resolved} is not one of the bus's local topics {self._local_names}: declare "
                "it, or readers composed before this publisher took it from DDS as well"
            )
        dds = lossless_publisher(node, msg_type, resolved, qos, lossless)
        return StreamPublisher(dds, topic, self)

    def _wake_deliver(self, topic: _Topic, raw: bytes) -> None:
        """A message of an outside topic, taken at a wake of its DDS reader."""
        # deferred in lock-step, and in realtime when the wake found the reader behind
        # (module notes): a bounded reader is a realtime one
        reader = topic.dds_reader
        self._in_wake = not reader.max_backlog or reader.batch_size > 1
        self._deliver(topic, raw)

    def _end_wake(self) -> None:
        """The DDS reader's wake is delivered: hand the deferred readers their messages."""
        self._in_wake = False
        self.flush()

    def _deliver(self, topic: _Topic, raw: bytes) -> None:
        for reader in topic.urgent:
            reader(raw)
        if not self._in_wake and not self._pending:  # (older messages still owed: after them)
            for reader in topic.deferred:
                reader(raw)
        elif topic.deferred:
            source = topic.dds_reader
            gap = source is not None and source.gap_before
            self._pending.extend((reader, raw, source, gap) for reader in topic.deferred)

    def _deliver_dropped(self, topic: _Topic, raw: bytes) -> None:
        if not self._flushing:
            self.flush()  # anything still deferred is older
        # polled within a flush, or a flush stopped at its slice: after the messages still owed
        if self._flushing or self._pending:
            self._pending.extend((reader, raw, None, False) for reader in topic.lossless)
            return
        for reader in topic.lossless:
            reader(raw)

    def _resume_later(self) -> bool:
        """Have the executor go on with the flush after what else is ready (False: no executor)."""
        if not self._resume_due:
            executor = self._resume_node.executor if self._resume_node is not None else None
            if executor is None:
                return False
            executor.create_task(self._resume_flush)
            self._resume_due = True
        return True

    def _resume_flush(self) -> None:
        """The executor's turn after a flush's slice is over: go on with the deferred work."""
        self._resume_due = False
        self.flush()

    def flush(self) -> None:
        """Hand the deferred readers what they are owed, in order (module notes).

        The DDS readers that defer (no catch-up bound: lock-step, where the plant publishes
        the next period as soon as the command arrives) are polled every :data:`POLL_PERIOD` s
        of this work, so that a message that arrived meanwhile reaches the urgent readers at
        once (its deferred deliveries join the queue). A realtime reader defers only the
        messages of a wake that found it behind (:meth:`_wake_deliver`) and is not polled.

        After :data:`FLUSH_SLICE` s of work the call returns with the rest still owed, and a
        task calls it again once the executor has served what else is ready (module notes).

        Each message's DDS reader shows, during the call, the ``gap_before`` it had when the
        message was taken (:func:`amb_tools.backlog.gap_known`). A reader's exception leaves
        the messages after it for the next flush and is raised.
        """
        if self._flushing or not self._pending:
            return  # a poll within a flush: the outer loop goes on
        self._flushing = True
        pending = self._pending
        sources = [
            t.dds_reader
            for t in self._topics.values()
            if t.dds_reader is not None and not t.dds_reader.max_backlog
        ]
        clock = time.perf_counter
        try:
            now = clock()
            next_poll = now + POLL_PERIOD
            slice_end = now + FLUSH_SLICE
            while pending:
                reader, raw, source, gap = pending.popleft()
                if source is None:
                    reader(raw)
                else:
                    source.gap_before = gap
                    try:
                        reader(raw)
                    finally:
                        source.gap_before = False
                now = clock()
                if pending and now > slice_end and self._resume_later():
                    break  # the rest after the executor's turn
                if sources and now > next_poll:
                    for src in sources:
                        src.poll()
                    next_poll = clock() + POLL_PERIOD
        finally:
            self._flushing = False


class StreamPublisher:
    """A DDS publisher whose messages (CDR bytes) also go to the bus's composed readers."""

    def __init__(self, dds, topic: _Topic, bus: LocalBus) -> None:
        self.dds = dds
        self._topic = topic
        self._bus = bus

    @property
    def topic_name(self) -> str:
        """The resolved topic name."""
        return self.dds.topic_name

    def publish(self, raw: bytes) -> None:
        """Publish serialised ``raw`` on DDS, then hand it to the composed readers."""
        self.dds.publish(raw)
        self._bus._deliver(self._topic, raw)


def stream_subscription(
    node: Node,
    bus: LocalBus | None,
    msg_type: type,
    name: str,
    callback: RawCallback,
    qos: QoSProfile,
    catch_up: CatchUp = NO_CATCH_UP,
    urgent: bool = False,
) -> BacklogReader | None:
    """Subscribe ``callback`` (raw CDR) to a stream: from the bus if composed, else from DDS.

    ``urgent``: on the control path, served first when composed (:meth:`LocalBus.subscribe`).
    Returns the DDS reader (:class:`amb_tools.backlog.BacklogReader`, its drop counts; shared
    by the composed readers of an outside topic), or None for a topic published in-process.
    """
    if bus is None:
        return BacklogReader(node, msg_type, name, callback, qos, catch_up)
    return bus.subscribe(node, msg_type, name, callback, qos, catch_up, urgent=urgent)


def stream_publisher(
    node: Node,
    bus: LocalBus | None,
    msg_type: type,
    name: str,
    qos: QoSProfile,
    lossless: bool = False,
):
    """A publisher of a stream (``publish(raw_bytes)``): bus-aware if composed.

    ``lossless``: keep every message until each reader has it, a publication waiting while the
    writer's history is full (lockstep; :mod:`amb_tools.lossless`).
    """
    if bus is None:
        return lossless_publisher(node, msg_type, name, qos, lossless)
    return bus.publisher(node, msg_type, name, qos, lossless)
