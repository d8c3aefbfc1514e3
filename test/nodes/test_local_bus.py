"""The in-process bus over real DDS: a catch-up drops for the control readers, not the recorder.

A :class:`~amb_tools.local_bus.LocalBus` feeds two readers of an outside topic from one DDS
reader bounded at 4 messages: a burst of 40 queued measurements (all acknowledged by the reader
before it spins) reaches the bounded reader as its newest 4 by the queue rule alone, one counted
overload, and the ``lossless`` reader (the composed recorder) as all 40, in order. With the age
rule as well, the burst taken 50 ms after it was published (40 messages within a few ms: 4 of
their intervals is far less) is too old, all of it, and all but the newest are dropped (the
newest of a wake always stays: the stream may end with it). A stream published in process
reaches its composed readers whole and an outside DDS reader from its match on.
"""

from __future__ import annotations

import threading
import time

import pytest
from amb_msgs.msg import Measurement, WaveletCoefficients
from rclpy.duration import Duration
from rclpy.serialization import serialize_message

from amb_tools.backlog import CatchUp
from amb_tools.cdr import read_coefficients, read_measurement
from amb_tools.local_bus import LocalBus
from amb_tools.streams import stream_qos

pytestmark = pytest.mark.ros

BURST = 40
BOUND = 4


@pytest.mark.parametrize("by_age", [False, True])
def test_a_catch_up_drop_reaches_the_lossless_reader_in_order(ros, by_age: bool) -> None:
    reader_node = ros.node(f"amb_test_bus_reader_{by_age:d}")
    driver = ros.node(f"amb_test_bus_driver_{by_age:d}")
    qos = stream_qos(16)
    pub = driver.create_publisher(Measurement, "/amb/measurement", qos)
    bus = LocalBus()
    bounded: list[int] = []
    everything: list[int] = []
    shared = bus.subscribe(
        reader_node, Measurement, "/amb/measurement",
        lambda raw: bounded.append(read_measurement(raw).sample_index), qos,
        catch_up=CatchUp(BOUND, by_age),
    )  # fmt: skip
    again = bus.subscribe(
        reader_node, Measurement, "/amb/measurement",
        lambda raw: everything.append(read_measurement(raw).sample_index), qos, lossless=True,
    )  # fmt: skip
    assert again is shared  # one DDS reader for the process
    assert ros.spin_until(lambda: pub.get_subscription_count() == 1, timeout=30.0)
    for k in range(BURST):
        pub.publish(serialize_message(Measurement(sample_index=k, samples_per_rev=16)))
    # every message is in the reader's queue (reliable: acknowledged) before it is taken
    assert pub.wait_for_all_acked(Duration(seconds=30.0))
    time.sleep(0.05)  # s: every message older than 4 of the burst's intervals when taken
    assert ros.spin_until(lambda: len(everything) >= BURST, timeout=30.0), (bounded, everything)
    assert everything == list(range(BURST))
    if by_age:
        assert bounded == [BURST - 1]
        assert (shared.dropped, shared.dropped_old, shared.episodes) == (BURST - 1, BOUND - 1, 1)
    else:
        assert bounded == list(range(BURST - BOUND, BURST))
        assert (shared.dropped, shared.dropped_old, shared.episodes) == (BURST - BOUND, 0, 1)


def test_a_local_stream_reaches_a_reader_outside_from_its_match_on(ros) -> None:
    """Published in process with no DDS reader, then with one: it gets the rest, in order."""
    writer_node = ros.node("amb_test_bus_writer")
    outside = ros.node("amb_test_bus_outside")
    qos = stream_qos(16)
    bus = LocalBus(local_topics=("/amb/wavelet/coefficients",))
    inside: list[int] = []
    pub = bus.publisher(writer_node, WaveletCoefficients, "/amb/wavelet/coefficients", qos)
    bus.subscribe(
        writer_node, WaveletCoefficients, "/amb/wavelet/coefficients",
        lambda raw: inside.append(read_coefficients(raw).sample_index), qos,
    )  # fmt: skip

    def message(k: int) -> bytes:
        return serialize_message(WaveletCoefficients(sample_index=k))

    for k in range(100):
        pub.publish(message(k))
    got: list[int] = []
    outside.create_subscription(
        WaveletCoefficients, "/amb/wavelet/coefficients", lambda m: got.append(m.sample_index),
        qos,
    )  # fmt: skip
    assert ros.spin_until(lambda: pub.dds.get_subscription_count() == 1, timeout=30.0)
    for k in range(100, 300):
        pub.publish(message(k))
    assert ros.spin_until(lambda: got and got[-1] == 299, timeout=30.0), got
    assert inside == list(range(300))  # the composed reader: everything
    assert got == list(range(100, 300))  # everything after the writer counted it matched


def _urgent_and_deferred(ros, name: str, catch_up: CatchUp | None):
    """A bus with a filterbank-like urgent reader that publishes a coefficient message per
    measurement, a controller-like urgent reader of those, and monitor-like deferred readers of
    both; returns (measurement publisher, log of (reader, sample index))."""
    node = ros.node(f"amb_test_bus_{name}")
    driver = ros.node(f"amb_test_bus_{name}_driver")
    qos = stream_qos(16)
    meas_pub = driver.create_publisher(Measurement, "/amb/measurement", qos)
    bus = LocalBus(local_topics=("/amb/wavelet/coefficients",))
    coef_pub = bus.publisher(node, WaveletCoefficients, "/amb/wavelet/coefficients", qos)
    log: list[tuple[str, int]] = []

    def filterbank(raw: bytes) -> None:
        k = read_measurement(raw).sample_index
        log.append(("filterbank", k))
        coef_pub.publish(serialize_message(WaveletCoefficients(sample_index=k)))

    def reader(name: str, read):
        return lambda raw: log.append((name, read(raw).sample_index))

    bound = {} if catch_up is None else {"catch_up": catch_up}
    bus.subscribe(node, Measurement, "/amb/measurement", filterbank, qos, urgent=True, **bound)
    bus.subscribe(node, Measurement, "/amb/measurement", reader("monitor", read_measurement), qos)
    for name, urgent in (("controller", True), ("monitor coefficients", False)):
        bus.subscribe(
            node, WaveletCoefficients, "/amb/wavelet/coefficients",
            reader(name, read_coefficients), qos, urgent=urgent,
        )  # fmt: skip
    assert ros.spin_until(lambda: meas_pub.get_subscription_count() == 1, timeout=30.0)
    return meas_pub, log


@pytest.mark.parametrize("mode", ["lockstep", "realtime"])
def test_urgent_readers_take_a_wake_before_the_deferred_ones(ros, mode: str) -> None:
    """A burst taken at one wake goes through the urgent readers (the control path) before the
    deferred ones (monitor, recorder), which still get every message of both streams in their
    order, a sample's coefficients before its measurement: in lock-step (no catch-up bound) and
    in realtime (bounded, here far above the burst), where a wake with several samples means the
    stack is behind."""
    catch_up = None if mode == "lockstep" else CatchUp(1000, False)
    meas_pub, log = _urgent_and_deferred(ros, f"urgent_{mode}", catch_up)
    n = 10
    for k in range(n):
        meas_pub.publish(serialize_message(Measurement(sample_index=k, samples_per_rev=16)))
    assert meas_pub.wait_for_all_acked(Duration(seconds=30.0))  # all queued before the wake
    assert ros.spin_until(lambda: len(log) >= 4 * n, timeout=30.0), log
    urgent = [e for k in range(n) for e in (("filterbank", k), ("controller", k))]
    deferred = [e for k in range(n) for e in (("monitor coefficients", k), ("monitor", k))]
    assert log == urgent + deferred


def test_a_realtime_wake_of_one_sample_serves_every_reader_at_once(ros) -> None:
    """In realtime a wake normally brings one sample: every reader gets it there, urgent ones
    first, with no deferral (its bookkeeping cost more than it gave: docs/history.md, "The
    control path first")."""
    meas_pub, log = _urgent_and_deferred(ros, "single", CatchUp(1000, False))
    n = 5
    for k in range(n):
        meas_pub.publish(serialize_message(Measurement(sample_index=k, samples_per_rev=16)))
        assert ros.spin_until(lambda k=k: len(log) >= 4 * (k + 1), timeout=30.0), log
    expected = [
        e
        for k in range(n)
        for e in (("filterbank", k), ("controller", k), ("monitor coefficients", k), ("monitor", k))
    ]
    assert log == expected


def test_a_lockstep_flush_that_never_runs_dry_still_lets_the_executor_run(ros) -> None:
    """In lock-step the flush polls the DDS reader between deferred deliveries, and a plant that
    answers each command at once always has the next period queued: the deferred work never ran
    dry while the plant ran, and as one callback it kept the executor from the process's other
    callbacks until the end (a long composed run's recorder held only its first ``queue_depth``
    commands). Here a deferred reader needs 2 ms a message while a thread publishes one every
    0.5 ms: a timer on the same executor must still run while that backlog is worked off."""
    node = ros.node("amb_test_bus_slices")
    driver = ros.node("amb_test_bus_slices_driver")
    qos = stream_qos(16)
    pub = driver.create_publisher(Measurement, "/amb/measurement", qos)
    bus = LocalBus()
    n = 800
    done: list[int] = []

    def deferred(raw: bytes) -> None:  # the monitor's work on one sample, made slow
        done.append(read_measurement(raw).sample_index)
        time.sleep(0.002)

    bus.subscribe(node, Measurement, "/amb/measurement", lambda raw: None, qos, urgent=True)
    bus.subscribe(node, Measurement, "/amb/measurement", deferred, qos)
    ticks: list[int] = []  # how far the deferred reader was at each timer call
    node.create_timer(0.02, lambda: ticks.append(len(done)))
    assert ros.spin_until(lambda: pub.get_subscription_count() == 1, timeout=30.0)

    def produce() -> None:
        for k in range(n):
            pub.publish(serialize_message(Measurement(sample_index=k, samples_per_rev=16)))
            time.sleep(0.0005)

    thread = threading.Thread(target=produce)
    thread.start()
    try:
        assert ros.spin_until_progress(lambda: len(done) >= n, lambda: len(done), stall=30.0)
    finally:
        thread.join()
    assert done == list(range(n))  # every message, in order
    during = [t for t in ticks if 0 < t < n]
    # 1.6 s of deferred work: about 80 timer periods; without the slices none ran during it
    assert len(during) >= 10, f"timer calls while the backlog was worked off: {during}"
