"""A stream reader that keeps every sample still takes, at each wake, all that is queued.

rclpy's executors hand a subscription one message per wake (the single-threaded executor: one
per wait; the ``EventsExecutor``: one per new-message event the middleware counts). A reader
that took only that one would stay behind by whatever its queue ever held beyond its wakes, for
the rest of the run (``docs/history.md``). Here 40 measurements are queued (all acknowledged)
before the executor runs once: the first wake of a :class:`~amb_tools.backlog.BacklogReader`
without a catch-up bound (lock-step) must deliver all 40, in order, dropping none.
"""

from __future__ import annotations

import time

import pytest
from amb_msgs.msg import Measurement
from rclpy.duration import Duration
from rclpy.serialization import serialize_message

from amb_tools.backlog import BacklogReader
from amb_tools.cdr import read_measurement
from amb_tools.streams import stream_qos

pytestmark = pytest.mark.ros

QUEUED = 40


def test_a_lockstep_reader_takes_its_whole_queue_at_one_wake(ros) -> None:
    reader_node = ros.node("amb_test_backlog_reader")
    driver = ros.node("amb_test_backlog_driver")
    qos = stream_qos(16)
    pub = driver.create_publisher(Measurement, "/amb/measurement", qos)
    got: list[int] = []
    reader = BacklogReader(
        reader_node, Measurement, "/amb/measurement",
        lambda raw: got.append(read_measurement(raw).sample_index), qos,
    )  # fmt: skip
    assert ros.spin_until(lambda: pub.get_subscription_count() == 1, timeout=30.0)
    for k in range(QUEUED):
        pub.publish(serialize_message(Measurement(sample_index=k, samples_per_rev=16)))
    assert pub.wait_for_all_acked(Duration(seconds=30.0))  # all in the reader's queue
    deadline = time.monotonic() + 30.0
    while not got and time.monotonic() < deadline:
        ros.executor.spin_once(timeout_sec=0.1)  # one wake (the driver has nothing to run)
    assert got == list(range(QUEUED)), got  # one wake: the whole queue, in order
    assert (reader.dropped, reader.episodes) == (0, 0)
