"""``recorder``: write topics of this project to a rosbag2 without a ROS install.

Subscribes raw (CDR bytes, no deserialisation) to every topic whose name matches one of the
``topics`` patterns, as it appears in the graph (resolved names: ``/rig1/amb/measurement`` for a
system started in namespace ``/rig1``), and writes each message to a rosbag2 with the
``rosbags`` library (MCAP by default, custom types registered from the ``amb_msgs`` ``.msg``
files). The subscription QoS follows the publishers: reliable unless one of them is best effort.
On SIGINT or SIGTERM the bag is closed cleanly. Counts per topic are published once per
``status_period`` on ``/diagnostics`` and logged at the end.

Parameters (ROS)
----------------
output : str
    Bag folder to create (must not exist).
topics : str[]
    Shell-style patterns of topic names (``*`` also matches ``/``); default ``amb/*`` and
    ``/diagnostics``. A relative pattern is taken under the recorder's namespace, as a relative
    topic name is (``amb/*`` is ``/rig1/amb/*`` in ``/rig1``, ``/amb/*`` at the root); an
    absolute one as it is. The bag holds the resolved (absolute) names.
topic_types : str[]
    ``topic:pkg/msg/Type`` entries subscribed at start, before any publisher is discovered, so
    that a run started right after the recorder loses nothing on them (reliable, volatile); a
    relative topic is resolved against the recorder's namespace.
storage : str
    ``mcap`` or ``sqlite3``.
stamp_source : str
    ``receive`` (node clock at reception, as ``ros2 bag record``) or ``header`` (the message's
    ``header.stamp``, for types whose first field is a header; receive time otherwise, and for
    a negative stamp, which a bag cannot store).
discovery_period : float
    s, how often the graph is scanned for new matching topics.
status_period : float
    s, how often counts are published on ``/diagnostics`` (0 = never).
queue_depth : int
    Subscription history depth; large enough that a reliable stream is never dropped.
drain_period : float
    s, how often the subscriptions' queues are emptied into the bag.

Messages are not handed over one callback at a time: the subscriptions belong to a callback
group the executor never runs (:class:`DrainedGroup`) and a timer takes everything queued on
each of them every ``drain_period`` (and once more before the bag is closed). The executor
therefore wakes at the timer's rate, not at the message rate: a wake of the
``SingleThreadedExecutor`` costs far more Python than taking one queued message (what a wake
per message cost the recorder: ``docs/history.md``, "Recorder: one wake per message").
The receive stamp (``stamp_source: receive``) is the middleware's reception time of each
message, so that it does not depend on when the queue was drained.

Composed (``wavelet_stack``, a :class:`~amb_tools.local_bus.LocalBus` given): the streams the
bus carries (the measurements the stack takes from DDS once, the coefficients its filterbank
publishes) are handed to the recorder in process, every message, including those the control
nodes skip to catch up after an overload (``lossless``); no DDS reader of its own for them, and
no subscriber for the stack's coefficient publisher to serve. The other topics are subscribed as
usual with an ordinary callback (the stack's ``EventsExecutor`` runs callbacks, not wait sets:
a :class:`DrainedGroup` is not for it), and a thread writes the bag
(:class:`~amb_tools.bag_writer.QueuedBagWriter`): the control thread only queues. The receive
stamp is then the node clock at the hand-over.
"""

from __future__ import annotations

import fnmatch
import importlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.callback_groups import CallbackGroup
from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)
from std_msgs.msg import Header

from amb_common import topics
from amb_tools.bag_writer import STORAGE_PLUGINS, BagWriter, QueuedBagWriter, header_stamp_ns
from amb_tools.local_bus import LocalBus
from amb_tools.node_main import ConfigurationError, descriptor, run_node
from amb_tools.reader_participant import (
    ClosesReaderParticipant,
    MovableReader,
    take_queued,
    watch_readers,
)

STAMP_SOURCES = ("receive", "header")


class DrainedGroup(CallbackGroup):
    """A callback group the executor never runs: its subscriptions are taken by the recorder.

    ``Executor.can_execute`` asks the group; an entity it refuses is left out of the wait set,
    so a message on such a subscription costs no executor wake. The middleware still queues
    every message (up to the subscription's depth) until the recorder takes it.
    """

    def can_execute(self, entity: Any) -> bool:
        """Never: the executor leaves the group's entities out of its wait set."""
        return False

    def beginning_execution(self, entity: Any) -> bool:
        """Never begin one (nothing of the group is executed)."""
        return False

    def ending_execution(self, entity: Any) -> None:
        """Nothing to release (nothing began)."""
        return None


class RecordedSubscription(MovableReader):
    """One recorded topic's DDS subscription: drained into the bag, and movable.

    ``poll`` writes every message queued now; ``subscribe_on``, ``switch`` and ``cancel`` move
    it to another node (a participant of the recorder's own,
    :class:`amb_tools.reader_participant.DeafReaders`): the same topic, QoS and callback group,
    the old subscription drained and destroyed, nothing written twice.
    """

    def __init__(
        self,
        node: Node,
        msg_class: type,
        topic: str,
        qos: QoSProfile,
        callback: Callable[[bytes], None],
        group: CallbackGroup | None,
        write: Callable[[bytes, dict], None],
    ) -> None:
        self._node = node
        self._callback = callback
        self._args = (msg_class, topic, self._on_raw, qos)
        self._group = group
        self._write = write
        self.subscription = node.create_subscription(*self._args, callback_group=group, raw=True)

    def _on_raw(self, raw: bytes) -> None:
        if self._fresh_from((raw,)):
            return  # written from the reader this one succeeded
        self._seen((raw,))
        self._callback(raw)

    def _write_all(self, taken: list[tuple[bytes, dict]]) -> None:
        raws = [raw for raw, _info in taken]
        first = self._fresh_from(raws)
        self._seen(raws[first:])
        for raw, info in taken[first:]:
            self._write(raw, info)

    def poll(self) -> int:
        """Write every message queued now to the bag; return how many."""
        taken = take_queued(self.subscription, self.subscription.msg_type, True)
        self._write_all(taken)
        return len(taken)

    def _subscribe(self, node: Node) -> Any:
        return node.create_subscription(*self._args, callback_group=self._group, raw=True)


def import_message_class(msgtype: str) -> type:
    """Return the rclpy message class of ``pkg/msg/Name``.

    Raises
    ------
    ImportError
        If the package is not built or not on ``PYTHONPATH``.
    """
    pkg, _, name = msgtype.split("/")
    return getattr(importlib.import_module(f"{pkg}.msg"), name)


def _has_header(msg_class: type) -> bool:
    fields = msg_class.get_fields_and_field_types()
    return bool(fields) and next(iter(fields.values())) == "std_msgs/Header"


class Recorder(ClosesReaderParticipant, Node):
    """Record matching topics to a rosbag2 (see the module docstring).

    Parameters
    ----------
    bus : amb_tools.local_bus.LocalBus, optional
        The streams of the process it is composed in; None: on its own.
    """

    def __init__(self, bus: LocalBus | None = None) -> None:
        super().__init__("recorder")
        self._bus = bus
        d = self.declare_parameter
        d("output", "", descriptor("bag folder to create"))
        d(
            "topics",
            [topics.PREFIX + "*", topics.DIAGNOSTICS],
            descriptor("topic name patterns to record (relative: under the node's namespace)"),
        )
        d("storage", "mcap", descriptor("mcap | sqlite3"))
        d("stamp_source", "receive", descriptor("receive | header"))
        d(
            "discovery_period",
            0.2,
            descriptor("graph scan period, s", read_only=False, floats=(0.01, 10.0)),
        )
        d(
            "status_period",
            1.0,
            descriptor(
                "period of the counts on /diagnostics, s (0 = off)",
                read_only=False,
                floats=(0.0, 60.0),
            ),
        )
        d(
            "topic_types",
            [""],
            descriptor(
                "topics to subscribe at start, before any publisher is seen, as "
                "'topic:pkg/msg/Type' ([''] = none; discovery by 'topics' goes on beside them)"
            ),
        )
        d(
            "queue_depth",
            10000,
            descriptor(
                "subscription history depth, messages", read_only=False, ints=(1, 1_000_000)
            ),
        )
        d(
            "drain_period",
            0.02,
            descriptor("how often the queues are written to the bag, s", floats=(0.001, 1.0)),
        )
        output = self.get_parameter("output").value
        storage = self.get_parameter("storage").value
        self._stamp_source = self.get_parameter("stamp_source").value
        patterns = list(self.get_parameter("topics").value)
        self._depth = self.get_parameter("queue_depth").value
        if not output:
            raise ConfigurationError("parameter 'output' (bag folder) is empty; set it")
        if Path(output).exists():
            raise ConfigurationError(f"parameter 'output' = {output!r}: the folder exists")
        if storage not in STORAGE_PLUGINS:
            raise ConfigurationError(
                f"parameter 'storage' = {storage!r}: allowed {sorted(STORAGE_PLUGINS)}"
            )
        if self._stamp_source not in STAMP_SOURCES:
            raise ConfigurationError(
                f"parameter 'stamp_source' = {self._stamp_source!r}: allowed {STAMP_SOURCES}"
            )
        if not patterns or not all(patterns):
            raise ConfigurationError(f"parameter 'topics' = {patterns!r}: empty pattern")
        # relative patterns match the names the node's relative topics resolve to
        self._patterns = [topics.absolute(p, self.get_namespace()) for p in patterns]
        if bus is None:
            self._bag = BagWriter(output, storage=storage)
        else:
            self._bag = QueuedBagWriter(output, storage=storage)
        self._recorded: dict[str, Any] = {}
        self._drained = DrainedGroup()
        self._readers: list[RecordedSubscription] = []
        self._diag_pub = self.create_publisher(DiagnosticArray, topics.DIAGNOSTICS, 10)
        self.create_timer(self.get_parameter("discovery_period").value, self._discover)
        status_period = self.get_parameter("status_period").value
        if status_period > 0:
            self.create_timer(status_period, self._publish_status)
        if bus is None:  # composed, the subscriptions have callbacks (module docstring)
            self.create_timer(self.get_parameter("drain_period").value, self.drain)
        for entry in self.get_parameter("topic_types").value:
            if not entry:
                continue
            topic, sep, msgtype = entry.partition(":")
            try:
                if not sep or not topic or msgtype.count("/") != 2:
                    raise ValueError("expected 'topic:pkg/msg/Type'")
                topic = self.resolve_topic_name(topic)
            except Exception as exc:  # rclpy raises its own name errors
                raise ConfigurationError(f"parameter 'topic_types' entry {entry!r}: {exc}") from exc
            self._subscribe(topic, msgtype)
        self._discover()
        # alone, the recorder's DDS readers move to a participant of their own when the
        # transport stops feeding them (amb_tools.reader_participant), watched on the
        # measurements; composed, the stack's filterbank watches the reader they come through
        self._measurements = self.resolve_topic_name(topics.MEASUREMENT)
        self._deaf = watch_readers(self, self._watched if bus is None else (), self._heard)
        self.get_logger().info(f"recording {self._patterns} to {output} ({storage})")

    def _watched(self) -> list[RecordedSubscription]:
        """The DDS readers, the measurements' first; none while those are not recorded.

        None either once the bag is closed: nothing more is written.
        """
        first = self._recorded.get(self._measurements)
        if not isinstance(first, RecordedSubscription) or self._bag.closed:
            return []
        return [first, *(r for r in self._readers if r is not first)]

    def _heard(self) -> int:
        """Measurements written so far (changes whenever one arrived)."""
        return self._bag.counts.get(self._measurements, 0)

    def _discover(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if topic in self._recorded:
                continue
            if not any(fnmatch.fnmatchcase(topic, p) for p in self._patterns):
                continue
            if len(types) != 1:
                self.get_logger().warning(
                    f"{topic} has {len(types)} types {types}: not recorded",
                    throttle_duration_sec=10.0,
                )
                continue
            self._subscribe(topic, types[0])

    def _qos_for(self, topic: str) -> QoSProfile:
        publishers = self.get_publishers_info_by_topic(topic)
        best_effort = any(
            p.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for p in publishers
        )
        latched = publishers and all(
            p.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in publishers
        )
        reliable = ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE
        return QoSProfile(
            history=HistoryPolicy.KEEP_LAST,
            depth=self._depth,
            reliability=reliable,
            durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
        )

    def _subscribe(self, topic: str, msgtype: str) -> None:
        try:
            msg_class = import_message_class(msgtype)
            self._bag.add_topic(topic, msgtype)
        except (ImportError, AttributeError, KeyError, ValueError) as exc:
            self.get_logger().error(f"cannot record {topic} ({msgtype}): {exc}")
            self._recorded[topic] = None
            return
        use_header = self._stamp_source == "header" and _has_header(msg_class)
        clock = self.get_clock()

        def write(raw: bytes, info: dict, topic: str = topic) -> None:
            t_ns = header_stamp_ns(raw) if use_header else info.get("received_timestamp") or -1
            if t_ns < 0:  # no middleware stamp; or a header stamp before 1970 (not storable)
                t_ns = clock.now().nanoseconds
            self._bag.write_raw(topic, t_ns, raw)

        if self._bus is not None and self._bus.carries(self, topic):
            self._bus.subscribe(
                self, msg_class, topic, lambda raw: write(raw, {}), self._qos_for(topic),
                lossless=True,
            )  # fmt: skip
            self._recorded[topic] = self._bus
            self.get_logger().info(f"recording {topic} [{msgtype}] (in process)")
            return
        if self._bus is None:
            callback, group = (lambda raw: None), self._drained  # never called: drained
        else:
            callback, group = (lambda raw: write(raw, {})), None
        # after a renewal, a topic found later is read from the new participant too
        node = self if self._deaf is None else self._deaf.readers_node
        reader = RecordedSubscription(
            node, msg_class, topic, self._qos_for(topic), callback, group, write
        )
        self._recorded[topic] = reader
        self._readers.append(reader)
        self.get_logger().info(f"recording {topic} [{msgtype}]")

    def drain(self) -> int:
        """Write every message queued on the subscriptions to the bag; return how many."""
        if self._bag.closed:
            return 0
        return sum(reader.poll() for reader in self._readers)

    def _publish_status(self) -> None:
        status = DiagnosticStatus(
            level=DiagnosticStatus.OK,
            name=topics.diagnostic_name("recorder", self.get_namespace()),
            message=f"{sum(self.counts.values())} messages written to {self._bag.path}",
            hardware_id=str(self._bag.path),
            values=[KeyValue(key=t, value=str(n)) for t, n in sorted(self.counts.items())]
            + [KeyValue(key="readers_renewed", value=str(self._deaf.renewals))],
        )
        self._diag_pub.publish(
            DiagnosticArray(header=_stamp(self.get_clock().now()), status=[status])
        )

    @property
    def counts(self) -> dict[str, int]:
        """Messages written so far, per topic (a copy: composed, a thread writes them)."""
        return dict(self._bag.counts)

    def on_shutdown(self) -> None:
        """Write what is still queued, close the bag and log what was written."""
        self.drain()
        self._bag.close()
        failed = getattr(self._bag, "failed", 0)
        if failed:
            self.get_logger().error(
                f"{failed} messages could not be written to the bag; first: {self._bag.error}"
            )
        summary = ", ".join(f"{t}: {n}" for t, n in sorted(self._bag.counts.items())) or "nothing"
        self.get_logger().info(f"bag {self._bag.path} closed; messages written: {summary}")


def _stamp(now: Any) -> Any:
    return Header(stamp=now.to_msg())


def main(args: list[str] | None = None) -> int:
    """Entry point of the ``recorder`` executable."""
    # The recorder keeps the SingleThreadedExecutor: with the EventsExecutor two fresh-clone CI
    # runs each produced an amb-run bag in which one whole topic (coefficients, then commands)
    # had no message, although every node received it; never seen with this executor.
    return run_node(Recorder, args, executor="single")


if __name__ == "__main__":
    raise SystemExit(main())
