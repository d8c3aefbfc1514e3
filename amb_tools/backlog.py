"""
Catching up after an overload: a stream reader that drops the oldest of a long backlog.

In ``realtime`` a node that falls behind the measurement stream (a CPU hog, a stopped process,
a slow disk under a composed recorder) finds its queue full of samples whose control periods
are over: processing them in order keeps it behind for as long as the backlog takes to drain,
and at a load close to one core that is for good. A :class:`BacklogReader` takes every queued
message at each wake (rclpy's executors hand them over one per callback) and drops the oldest
when it is more than ``max_backlog`` messages behind: one counted, logged gap per overload
instead of a backlog that never drains. The readers downstream see an ordinary discontinuity
(:class:`amb_tools.validation.SampleSequencer`: the filterbank resets at the new index, the
controller resets its filters, the fault monitor calibrates again) once per episode, not once
per late sample.

"Behind" is counted two ways, and a message is dropped by either:

- *queued*: more than ``max_backlog`` messages are waiting at this wake;
- *old*: the message was published more than ``max_backlog`` message intervals ago. A reader let
  go after a stall (a stopped process, a CPU hog) does not find the stall's messages in its
  queue at once: they arrive over several wakes (after a 1 s SIGSTOP of a reader of a 1 kHz
  reliable stream, in batches of 512, 73, 183 and 278), and with the queue rule alone the newest
  ``max_backlog`` of each batch are kept although every one is too old for its control period
  (256 messages up to 0.65 s old delivered in one such run with ``max_backlog = 128``; issue 17:
  commands missing for up to 11 periods after the release). The age is the reader's wall clock
  less the DDS source timestamp (the writer's wall clock at the publish, ``rmw_message_info``)
  less the stream's smallest transport time (its latency and any offset between the two clocks:
  a writer on another computer needs only clocks that do not drift apart; ``max_backlog_by_age:
  false`` leaves the queue rule alone), in units of the writer's mean interval between
  publishes (source timestamps over DDS publication sequence numbers), whatever the reader's
  delays (:class:`MessageAge`). Simulated time and the plant's
  ``time_scale`` play no part.

The newest message of a wake is never dropped: however old, it is the newest the reader has, and
the stream may end with it (a reader that dropped it would never process the last sample of a
run, and ``amb-run``'s drain would wait for it).

``max_backlog = 0`` (the default) keeps every sample: ``lockstep`` needs all of them and is
never behind by more than the periods the plant waits for. Every wake takes all that is queued,
also then: rclpy's executors take one message per new-message event the middleware counts
(the ``EventsExecutor`` exactly as many as the count), so a reader whose queue ever holds a
message no event stands for would stay that many messages behind for the rest of the run, a
steady lag no spare CPU works off (a lock-step controller after a starvation: every command
eight periods late until the end, ``docs/history.md``). An event whose message a drain took
already finds nothing and calls nothing. Every node that reads the
measurement stream declares the parameters (:func:`declare_catch_up`) and bounds with them
its DDS readers of both streams: ``max_backlog`` samples' worth of each, so the coefficient
readers of the controller and the monitor keep half as many messages
(:meth:`CatchUp.per_message`; one per two samples: as a message count the same bound left the
controller 4 periods of coefficients behind after a stop, with one core busy); composed in one
process (:mod:`amb_tools.local_bus`) the nodes
share one measurement reader, which takes the values of the first (the filterbank's), and the
coefficients are handed over in-process, never queued.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable
from typing import Any, NamedTuple

from rclpy.node import Node
from rclpy.qos import QoSProfile

from amb_tools.node_main import descriptor
from amb_tools.reader_participant import MovableReader
from amb_tools.throttled_log import ThrottledWarnings

__all__ = [
    "BY_AGE",
    "MAX_BACKLOG",
    "NO_CATCH_UP",
    "BacklogReader",
    "CatchUp",
    "MessageAge",
    "backlog_counts",
    "declare_catch_up",
    "gap_known",
]

#: Name of the ROS parameter (samples; 0 = keep every sample).
MAX_BACKLOG = "max_backlog"
#: Name of the ROS parameter switching the age rule (module docstring) on or off.
BY_AGE = "max_backlog_by_age"


class CatchUp(NamedTuple):
    """
    A reader's catch-up bound (module docstring).

    Attributes
    ----------
    max_backlog : int
        Messages a reader may be behind; 0: keep every message.
    by_age : bool
        Count "behind" by age as well as in the queue.
    """

    max_backlog: int = 0
    by_age: bool = True

    @property
    def keeps_every_message(self) -> bool:
        """No bound (``max_backlog`` 0, lockstep): its own streams lose nothing either.

        The node's stream writers then keep every message until each reader has it
        (:mod:`amb_tools.lossless`).
        """
        return not self.max_backlog

    def per_message(self, samples: int) -> CatchUp:
        """
        The bound for a stream of one message per ``samples`` samples: as long behind in time.

        Parameters
        ----------
        samples : int
            Samples per message (>= 1; the coefficients: ``SAMPLES_PER_COEFFICIENT_MESSAGE``).

        Returns
        -------
        CatchUp
            ``max_backlog // samples`` messages (at least 1); unchanged if 0 (keep every one).
        """
        if samples < 1:
            raise ValueError(f"samples per message = {samples}: must be >= 1")
        if not self.max_backlog:
            return self
        return self._replace(max_backlog=max(1, self.max_backlog // samples))


#: Keep every message (lockstep, and the default of every reader).
NO_CATCH_UP = CatchUp()


def declare_catch_up(node: Node) -> CatchUp:
    """
    Declare ``max_backlog`` and ``max_backlog_by_age`` on ``node`` (read-only); return them.

    Returns
    -------
    CatchUp
    """
    node.declare_parameter(
        MAX_BACKLOG,
        0,
        descriptor(
            "realtime catch-up, in samples: measurements queued behind more than this many, or "
            "published more than this many sample intervals ago, are dropped (a counted gap; "
            "the newest of each take stays), coefficient messages (one per two samples) beyond "
            "half as many; 0 = keep every message (lockstep), and publish this node's streams "
            "keeping every message until each reader has it (a publication waits for a reader "
            "far behind; amb_tools.lossless)",
            ints=(0, 1 << 20),
        ),
    )
    node.declare_parameter(
        BY_AGE,
        True,
        descriptor(
            "realtime catch-up by age as well (DDS source timestamps: the writer's and the "
            "reader's clocks must not drift apart; false for a bridge on another computer "
            "whose clock is not synchronised with this one's)"
        ),
    )
    return CatchUp(
        int(node.get_parameter(MAX_BACKLOG).value), bool(node.get_parameter(BY_AGE).value)
    )


class BacklogReader(MovableReader):
    """
    A raw DDS subscription that hands over its messages in order, dropping a long backlog.

    Parameters
    ----------
    node : rclpy.node.Node
        The node holding the subscription.
    msg_type : type
        Message class.
    name : str
        Topic name.
    deliver : callable
        Called with the CDR bytes of each message kept, oldest first.
    qos : rclpy.qos.QoSProfile
        QoS of the subscription.
    catch_up : CatchUp
        Messages a reader may be behind, queued or (``by_age``) by age (module docstring);
        ``max_backlog`` 0: every message is delivered.
    on_dropped : callable, optional
        Called with the CDR bytes of each message dropped, oldest first, before the kept ones
        are delivered (a reader that must lose nothing: a composed recorder).
    after_batch : callable, optional
        Called after the messages of a wake are delivered (the composed readers that were
        deferred until then, :class:`amb_tools.local_bus.LocalBus`).

    Attributes
    ----------
    dropped : int
        Messages dropped so far (queued or old).
    dropped_old : int
        Of those, messages dropped for their age alone (fewer than ``max_backlog`` queued).
    episodes : int
        Wakes that dropped messages (overloads caught up).
    gap_before : bool
        True while the first message kept after a drop is being delivered: the readers'
        sample indices jump there by what was dropped, a gap known to be real
        (:meth:`amb_tools.validation.SampleSequencer.push`, ``gap_known``).
    batch_size : int
        Messages kept at the wake being delivered (1 outside a wake): more than one, and the
        reader is behind its stream (:class:`amb_tools.local_bus.LocalBus` then serves the
        control path first).

    Notes
    -----
    Movable to another participant (:class:`amb_tools.reader_participant.MovableReader`): a
    reader the transport stopped feeding is moved by
    :class:`amb_tools.reader_participant.DeafReaders`; counts and the age estimate carry over
    (the writer is the same).
    """

    def __init__(
        self,
        node: Node,
        msg_type: type,
        name: str,
        deliver: Callable[[bytes], None],
        qos: QoSProfile,
        catch_up: CatchUp = NO_CATCH_UP,
        on_dropped: Callable[[bytes], None] | None = None,
        after_batch: Callable[[], None] | None = None,
    ) -> None:
        max_backlog = catch_up.max_backlog
        if max_backlog < 0:
            raise ValueError(f"max_backlog = {max_backlog}: must be >= 0 (0 = keep every sample)")
        self._deliver = deliver
        self._on_dropped = on_dropped
        self._after_batch = after_batch
        self._msg_type = msg_type
        self.max_backlog = int(max_backlog)
        self.dropped = self.dropped_old = self.episodes = 0
        self.gap_before = False  # the message being delivered follows messages dropped here
        self.batch_size = 1
        self._received = 0  # messages taken, for a middleware without sequence numbers
        self._age = MessageAge(max_backlog) if max_backlog and catch_up.by_age else None
        self._warnings = ThrottledWarnings(node.get_logger(), period=5.0)
        self._qos = qos
        self._node = node
        self.subscription = node.create_subscription(
            msg_type, name, self._on_message, qos, raw=True
        )

    def _subscribe(self, node: Node) -> Any:
        return node.create_subscription(
            self._msg_type, self.subscription.topic_name, self._on_message, self._qos, raw=True
        )

    def poll(self) -> None:
        """Take and deliver, as at a wake, whatever is queued now.

        For a caller busy with other work that wants newer messages first (a composed bus's
        deferred readers, :meth:`amb_tools.local_bus.LocalBus.flush`).
        """
        self._on_message(None)

    def _take(self) -> tuple[list[bytes], list[int], list[int], list[int]]:
        """Every message queued now with its source and reception stamps and sequence number."""
        batch: list[bytes] = []
        sent: list[int] = []
        received: list[int] = []
        sequence: list[int] = []
        sub = self.subscription
        with sub.handle:  # as rclpy's executors take: every message queued now
            while (taken := sub.handle.take_message(self._msg_type, True)) is not None:
                batch.append(taken[0])
                info = taken[1]
                sent.append(info["source_timestamp"])
                received.append(info["received_timestamp"])
                sequence.append(info.get("publication_sequence_number") or 0)
        return batch, sent, received, sequence

    def _on_message(self, raw: bytes | None) -> None:
        # the executor's message comes without its message info (rclpy's EventsExecutor fails on
        # a callback that asks for it); the rest are taken with it, for their source timestamps
        self._process(raw, *self._take())

    def _process(
        self,
        raw: bytes | None,
        taken: list[bytes],
        sent: list[int],
        received: list[int],
        sequence: list[int],
    ) -> None:
        batch = taken if raw is None else [raw, *taken]
        if not batch:
            return
        first = self._fresh_from(batch)  # after a move: less what the old reader delivered
        if first:
            cut = first - (raw is not None)  # the executor's message has no info columns
            raw = None
            batch = batch[first:]
            sent, received, sequence = sent[cut:], received[cut:], sequence[cut:]
            if not batch:
                return
        self._seen(batch)  # a successor made for a move may hold these too
        self._received += len(batch)
        queued = max(len(batch) - self.max_backlog, 0) if self.max_backlog else 0
        old = 0
        if self._age is not None:
            if not all(sequence):  # no numbers from this middleware: count what came instead
                sequence = list(range(self._received - len(sent), self._received))
            old = self._age.old(sent, time.time_ns(), received, sequence=sequence)
            if raw is not None:
                old += old > 0  # the executor's message is older than the first one taken here
        excess = min(max(queued, old), len(batch) - 1)  # the newest stays (module docstring)
        if excess > 0:
            self.dropped += excess
            self.dropped_old += excess - queued
            self.episodes += 1
            why = (
                f"{len(batch)} messages queued, more than max_backlog = {self.max_backlog}"
                if queued >= old
                else f"{old} of {len(batch)} queued messages older than max_backlog = "
                f"{self.max_backlog} message intervals ({self._age.limit_s * 1e3:.3g} ms)"
            )
            self._warnings.warning(
                "backlog",
                f"{self.subscription.topic_name}: {why}: the oldest {excess} dropped to catch up "
                f"({self.dropped} in {self.episodes} overloads so far)",
            )
            if self._on_dropped is not None:
                for item in batch[:excess]:
                    self._on_dropped(item)
            del batch[:excess]
        error: Exception | None = None
        self.batch_size = len(batch)
        for k, item in enumerate(batch):
            self.gap_before = excess > 0 and k == 0
            try:
                self._deliver(item)
            except Exception as exc:  # the rest of the wake is still delivered; raised after
                error = error or exc
        self.gap_before = False
        self.batch_size = 1
        if self._after_batch is not None:
            try:
                self._after_batch()
            except Exception as exc:
                error = error or exc
        if error is not None:
            raise error


class MessageAge:
    """
    How many of a run of consecutive messages are older than ``max_backlog`` message intervals.

    The age of a message is its reader's wall clock at the take less the writer's at the
    publish (the DDS source timestamp), less the floor: the smallest transport time seen on the
    stream, the reader's DDS reception stamp less the source timestamp (the transport's latency
    and any offset between the two clocks; a message that waited in the reader's queue, or in
    the writer's for a stopped reader, still shows it when it was received before the wait, so
    that the floor is known from the first wake that finds two messages).

    The interval is the writer's mean spacing of its publishes over spans of at least
    ``max_backlog`` of them: the source timestamps of a span's two ends divided by the
    difference of their publication sequence numbers (DDS numbers every message a writer
    publishes), so that neither a burst (a realtime plant whose timer fired late releases
    several samples within microseconds) nor messages the reader never received (a stalled
    reader whose queue overflowed) bias it. Spacings measured between the messages a reader
    happens to take together do not do: those runs are the bursts, and in the overload test
    they put the bound at 2-42 ms instead of 182 ms, dropping fresh samples
    (``docs/history.md``, "Catch-up by age"). The spans follow each other (each starts where the
    last ended) and the interval is the median of the last :attr:`SPANS`, so that neither a span
    over a pause of the writer (a filterbank stopped with its reader: its coefficients stop, the
    clock goes on) stretches the bound nor one over the realtime plant's start-up burst (up to
    ~100 samples at once; one such span gave a bound of 65 ms instead of 182 ms) shrinks it,
    and a speed change is followed within three spans. Until three spans are complete it is the
    larger of those there are (a stop in the first second of a run must find a bound: waiting
    for three spans left the queue rule alone in 2 of 12 overload tests with one core busy), so
    the start-up burst shortens it only until the second span. Until the first span is complete
    no message is old. A sequence number that does not increase (a restarted writer) starts the
    estimate afresh.

    A run is the messages a reader takes at one wake after the executor's own
    (:class:`BacklogReader`): the executor's message comes without its message info, so a reader
    that keeps up (one message per wake) gives none, and the floor and the interval come from
    the wakes that found two or more queued; until then a reader drops by the queue rule alone.
    ROS-free, so that the rule is tested on its own (``test/reliability/test_backlog_age.py``).

    Parameters
    ----------
    max_backlog : int
        Bound, in messages (>= 1).
    """

    #: Spans whose median is the interval.
    SPANS = 3

    def __init__(self, max_backlog: int) -> None:
        if max_backlog < 1:
            raise ValueError(f"max_backlog = {max_backlog}: must be >= 1")
        self.max_backlog = int(max_backlog)
        self._span_start: tuple[int, int] | None = None  # (sequence number, source stamp ns)
        self._spans: deque[float] = deque(maxlen=self.SPANS)  # mean spacings, ns
        self._interval: float | None = None  # ns
        self._floor: int | None = None

    @property
    def interval_s(self) -> float:
        """The estimated spacing of the writer's publishes, s (nan until known)."""
        return math.nan if self._interval is None else self._interval * 1e-9

    @property
    def limit_s(self) -> float:
        """The age bound, ``max_backlog`` intervals, s (inf until the interval is known)."""
        return math.inf if self._interval is None else self.max_backlog * self._interval * 1e-9

    def _estimate(self, sequence: list[int], sent: list[int]) -> None:
        for point in ((sequence[0], sent[0]), (sequence[-1], sent[-1])):
            start = self._span_start
            if start is not None and point[0] < start[0]:
                self._spans.clear()  # a new writer (or a restarted one): its own rate
                self._interval = None
                start = None
            if start is None:
                self._span_start = point
            elif point[0] - start[0] >= self.max_backlog and point[1] > start[1]:
                self._spans.append((point[1] - start[1]) / (point[0] - start[0]))
                self._span_start = point
                spans = sorted(self._spans)
                # the median of three; until then the larger (a burst only shortens a span)
                self._interval = spans[1] if len(spans) == self.SPANS else spans[-1]

    def old(
        self,
        sent: list[int],
        now: int,
        received: list[int] | None = None,
        *,
        sequence: list[int],
    ) -> int:
        """
        Record a run of consecutive messages and return how many of its first are too old.

        Parameters
        ----------
        sent : list of int
            Source timestamps of the run, oldest first, ns (wall clock); may be empty.
        now : int
            The reader's wall clock at the take, ns.
        received : list of int, optional
            The reader's DDS reception stamps of the run, ns (wall clock); None: each taken on
            arrival (``now``).
        sequence : list of int
            The writer's publication sequence numbers of the run (:class:`BacklogReader` counts
            the messages it received when the middleware gives no numbers).

        Returns
        -------
        int
            The length of the run's prefix older than the bound (0 .. ``len(sent)``).
        """
        if not sent:
            return 0
        self._estimate(sequence, sent)
        if received is None:
            floor = now - sent[-1]
        else:
            floor = min(r - t for r, t in zip(received, sent, strict=True))
        self._floor = floor if self._floor is None else min(self._floor, floor)
        if self._interval is None:
            return 0
        limit = self.max_backlog * self._interval + self._floor
        newest_old = -1
        for k, t in enumerate(sent):
            if now - t > limit:
                newest_old = k
        return newest_old + 1


def gap_known(reader: BacklogReader | None) -> bool:
    """Whether the message ``reader`` is delivering follows messages it dropped (a known gap).

    For :meth:`amb_tools.validation.SampleSequencer.push`; None (a stream handed over
    in-process, never dropped): False.
    """
    return reader is not None and reader.gap_before


def backlog_counts(*readers: BacklogReader | None) -> dict[str, int]:
    """The ``/diagnostics`` values of a node's readers: drops, drops for age alone, overloads.

    Summed over the readers given (None: a stream handed over in-process, never behind).
    """
    own = [r for r in readers if r is not None]
    return {
        "backlog_dropped": sum(r.dropped for r in own),
        "backlog_dropped_old": sum(r.dropped_old for r in own),
        "backlog_overloads": sum(r.episodes for r in own),
    }
