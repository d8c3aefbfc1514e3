"""Black box: pre/post-trigger windows written to a bag, read back with rosbags (not the code)."""

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from amb_fault_monitor.blackbox import BlackBox
from amb_fault_monitor.errors import FaultMonitorError
from amb_tools.bag_types import typestore

TOPIC = "/amb/test/value"
TYPE = "std_msgs/msg/Float64"


def _raw(store, v: float) -> bytes:
    Float64 = store.types[TYPE]
    return bytes(store.serialize_cdr(Float64(data=v), TYPE))


def test_pre_and_post_trigger_windows(tmp_path):
    store = typestore()
    box = BlackBox(tmp_path, pre_s=0.5, post_s=0.25)
    dt = 10_000_000  # 10 ms
    path = None
    for i in range(300):
        if i == 200:
            assert box.trigger(i * dt, "event_1")
            assert not box.trigger(i * dt, "event_2")  # inside the open capture
        out = box.add(TOPIC, TYPE, i * dt, _raw(store, float(i)))
        path = path or out
    assert path == tmp_path / "event_1" and not box.capturing
    with AnyReader([path], default_typestore=store) as reader:
        rows = [(t, reader.deserialize(raw, c.msgtype).data) for c, t, raw in reader.messages()]
        topics = [c.topic for c in reader.connections]
    values = np.array([v for _t, v in rows])
    # 0.5 s before the trigger (stamps 1.50 .. 2.00 s) to 0.25 s after (2.25 s completes it)
    np.testing.assert_array_equal(values, np.arange(150, 226))
    assert rows[0][0] == 150 * dt
    assert topics == [TOPIC]


def test_buffer_only_holds_pre_window():
    box = BlackBox("/nonexistent", pre_s=0.1, post_s=0.1)
    for i in range(1000):
        box.add(TOPIC, TYPE, i * 1_000_000, b"\x00\x01\x00\x00")
    assert len(box._bufs[TOPIC]) == 101


def test_negative_lengths_refused():
    with pytest.raises(FaultMonitorError, match=">= 0 s"):
        BlackBox("x", -1.0, 1.0)


def test_lagging_stream_keeps_its_own_pre_window(tmp_path):
    # the measurement stream runs 0.5 s ahead of the coefficients; the event comes from the
    # lagging stream: the bag still holds both over [t - pre, t + post]
    box = BlackBox(tmp_path, pre_s=0.2, post_s=0.1)
    dt = 10_000_000
    path = None
    for i in range(300):
        out = box.add("/m", TYPE, i * dt, b"\x00\x01\x00\x00")
        path = path or out
        if i >= 50:
            j = i - 50
            if j == 150:
                box.trigger(j * dt, "ev")
            path = path or box.add("/c", TYPE, j * dt, b"\x00\x01\x00\x00")
    with AnyReader([path], default_typestore=typestore()) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
    assert counts == {"/m": 31, "/c": 31}  # stamps 1.30 .. 1.60 s on both
