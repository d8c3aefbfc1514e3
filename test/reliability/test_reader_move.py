"""A reader's move to a new participant loses nothing and delivers nothing twice.

A writer process publishing at 100 Hz is stopped (SIGSTOP) for longer than the reader's
``reader_renewal_after``, with the reader's side matched all along: the reader begins a move to a
new participant (:class:`amb_tools.reader_participant.DeafReaders`), whose reader cannot match
a writer whose process is stopped. When the writer runs again, either the old reader gets the
stream first and the move is called off, or the new reader matched first and the readers
switch over, less what the old one delivered meanwhile. Either way every message arrives once
and in order. The move that destroyed the old reader first lost what was published before the
new one matched (stop 53: 56 samples of a test's observer held by a stopped recorder).

The reader is the tests' :class:`StreamTap` (a ``BacklogReader`` watched by ``DeafReaders``, as
in the nodes); the writer a process of its own (:func:`writer_process.writer_script`).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message
from std_msgs.msg import String
from writer_process import writer_script

from amb_tools.reader_participant import MovableSubscription, ReaderParticipant, has_queued

pytestmark = [pytest.mark.ros]

TOPIC = "/amb_test/reader_move"
MESSAGES = 600  # 6 s at 100 Hz
RENEW_AFTER = 1.0  # s
WRITER = writer_script(
    "amb_test_reader_move_writer",
    TOPIC,
    "depth=100",
    f"""
for k in range({MESSAGES}):
    pub.publish(String(data=str(k)))
    time.sleep(0.01)
if not pub.wait_for_all_acked(Duration(seconds=30.0)):
    sys.exit("not acknowledged in 30 s")
""",
)


def test_a_move_during_a_stopped_writer_loses_nothing(ros) -> None:
    node = ros.node("amb_test_reader_move")
    tap = ros.tap(node, String, TOPIC, 16, renew_after=RENEW_AFTER)
    writer = subprocess.Popen(
        [sys.executable, "-c", WRITER], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        received = lambda: tap.received  # noqa: E731
        assert ros.spin_until_progress(lambda: tap.received >= 100, received, stall=60.0)
        os.kill(writer.pid, signal.SIGSTOP)
        try:
            # the move begins after RENEW_AFTER s of silence (checked every 0.25 s)
            assert ros.spin_until(lambda: tap.deaf.moving, 10 * RENEW_AFTER), (
                f"no move began: renewals {tap.renewals}, received {tap.received}"
            )
            ros.spin_for(0.5)  # the new reader cannot match the stopped writer meanwhile
            assert tap.deaf.moving, "the move ended while the writer was stopped"
        finally:
            os.kill(writer.pid, signal.SIGCONT)
        deadline = time.monotonic() + 120.0
        while writer.poll() is None and time.monotonic() < deadline:
            ros.spin_for(0.1)
        ros.spin_until_progress(lambda: tap.received >= MESSAGES, received, stall=5.0)
    finally:
        if writer.poll() is None:
            writer.kill()
        out, err = writer.communicate()
    assert writer.returncode == 0, f"writer failed:\n{out}\n{err}"
    data = [int(deserialize_message(raw, String).data) for raw in tap.raw]
    outcome = f"moves completed {tap.renewals}, called off {tap.deaf.called_off}"
    assert tap.renewals + tap.deaf.called_off == 1, outcome
    assert data == list(range(MESSAGES)), (
        f"{outcome}; received {len(data)} of {MESSAGES}: lost "
        f"{sorted(set(range(MESSAGES)) - set(data))[:20]}, repeated "
        f"{len(data) - len(set(data))}"
    )


def test_a_stream_running_through_a_move_is_handed_over_without_a_gap(ros) -> None:
    """A reader fed all along moves to a new participant as soon as it is ready, and its stream
    (100 Hz from a writer process) arrives once, in order, across the switch. Ready
    (:meth:`MovableReader.ready`) came only with a message in the successor's queue: the
    writer's side of the match, which the successor's publisher count does not show (stop 58's
    CI lost a recorder's command there)."""
    node = ros.node("amb_test_reader_handover")
    got: list[int] = []
    reader = MovableSubscription(
        node, String, TOPIC, lambda msg: got.append(int(msg.data)), QoSProfile(depth=100)
    )
    writer = subprocess.Popen(
        [sys.executable, "-c", WRITER], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    participant = None
    try:
        assert ros.spin_until_progress(lambda: len(got) >= 100, lambda: len(got), stall=60.0)
        participant = ReaderParticipant(node)  # made at the move, as DeafReaders makes it
        successor = reader.subscribe_on(participant.node)
        at_start = len(got)
        # asked from the successor's own match on (reader side; its writer's may lag 0.3 s)
        assert ros.spin_until(lambda: successor.get_publisher_count() > 0, 30.0, step=0.005)
        ready = ros.spin_until(reader.ready, 10.0, step=0.005)
        queued = has_queued(successor, participant.node.context)
        fed = len(got) - at_start
        reader.switch()
        switched_at = len(got)
        participant.start()
        ros.spin_until_progress(lambda: len(got) >= MESSAGES, lambda: len(got), stall=5.0)
        ros.spin_until(lambda: writer.poll() is not None, 60.0)  # the writer's acks come in
    finally:
        if participant is not None:
            participant.close()
        if writer.poll() is None:
            writer.kill()
        out, err = writer.communicate()
    assert writer.returncode == 0, f"writer failed:\n{out}\n{err}"
    assert ready, "the successor was not ready in 10 s"
    assert fed > 0 and queued, f"ready with {fed} messages delivered meanwhile, queued {queued}"
    assert got == list(range(MESSAGES)), (
        f"received {len(got)} of {MESSAGES}: lost {sorted(set(range(MESSAGES)) - set(got))[:20]}, "
        f"repeated {len(got) - len(set(got))}; switched after {switched_at}: "
        f"{got[max(switched_at - 10, 0) : switched_at + 30]}"
    )
