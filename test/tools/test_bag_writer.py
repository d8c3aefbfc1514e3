"""The recorder's threaded bag writer writes every queued message, in order (read by rosbags).

Reference: ``rosbags``' own reader and deserialiser of the bag written.
"""

from __future__ import annotations

import numpy as np
from rosbags.rosbag2 import Reader

from amb_tools.bag_types import typestore
from amb_tools.bag_writer import QueuedBagWriter

MEASUREMENT = "amb_msgs/msg/Measurement"


def _measurement(store, k: int) -> bytes:
    cls = store.types[MEASUREMENT]
    msg = store.types["std_msgs/msg/Header"](
        stamp=store.types["builtin_interfaces/msg/Time"](sec=k // 1000, nanosec=k % 1000),
        frame_id="rig",
    )
    fields = {name: 0 for name in cls.__dataclass_fields__ if name not in ("header", "__msgtype__")}
    for name, size in (("displacement", 8), ("current", 4), ("bearing_force", 4),
                       ("wavelet_force", 4)):  # fmt: skip
        fields[name] = np.full(size, float(k))
    fields.update(rotor_angle=0.0, rotor_speed=1.0, sample_index=k, samples_per_rev=32)
    return bytes(store.serialize_cdr(cls(header=msg, **fields), MEASUREMENT))


def test_every_queued_message_is_written_in_order_and_a_failed_write_is_counted(tmp_path) -> None:
    store = typestore()
    bag = QueuedBagWriter(tmp_path / "bag", period=0.005)
    bag.add_topic("/amb/measurement", MEASUREMENT)
    raws = [_measurement(store, k) for k in range(600)]
    for k, raw in enumerate(raws):
        bag.write_raw("/amb/measurement", 1_000 + k, raw)
        if k == 300:
            bag.write_raw("/not/declared", 5, raw)  # its write fails in the thread, counted
    bag.close()
    bag.close()  # twice is harmless
    assert bag.closed and bag.queued == 0
    assert bag.failed == 1 and isinstance(bag.error, KeyError)
    assert bag.counts["/amb/measurement"] == 600
    with Reader(tmp_path / "bag") as reader:
        got = [(t, raw) for _conn, t, raw in reader.messages()]
    assert [t for t, _ in got] == [1_000 + k for k in range(600)]
    assert [bytes(raw) for _, raw in got] == raws
    last = store.deserialize_cdr(got[-1][1], MEASUREMENT)
    assert last.sample_index == 599 and last.displacement[0] == 599.0
