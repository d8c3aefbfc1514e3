"""The join of the measurement and coefficient streams (``amb_controller.stream_join``), without
DDS: every delivery order gives the same samples in index order, each odd sample with its own
coefficients; the coefficient timeout counts from the stream's progress; refusals are counted
and reported; a restart releases the old stream's tail."""

from __future__ import annotations

import math
import random
from dataclasses import dataclass

from amb_controller.stream_join import COEFFICIENT_HORIZON_PERIODS, StreamJoin
from amb_tools.validation import SampleSequencer

SPR = 16  # samples per revolution and per control period
OMEGA = 2.0 * math.pi * 10.0  # rad/s
DT = 2.0 * math.pi / (SPR * OMEGA)  # s between samples
TIMEOUT = 1.0  # s


@dataclass(frozen=True)
class Stamp:
    sec: int
    nanosec: int


@dataclass(frozen=True)
class Header:
    stamp: Stamp


@dataclass(frozen=True)
class Meas:
    sample_index: int
    rotor_speed: float
    header: Header


@dataclass(frozen=True)
class Coeffs:
    sample_index: int
    header: Header
    wavelet: str = "haar"
    samples_per_rev: int = SPR


def stamp_of(n: int, t0: float = 0.0) -> Header:
    t = t0 + n * DT
    return Header(Stamp(int(t), round((t - int(t)) * 1e9)))


def meas(n: int, t0: float = 0.0) -> tuple[Meas, float]:
    return Meas(n, OMEGA, stamp_of(n, t0)), t0 + n * DT


def coeffs(n: int, **kw) -> Coeffs:
    return Coeffs(n, stamp_of(n), **kw)


class Sink:
    def __init__(self) -> None:
        self.reports: list[tuple[str, str]] = []

    def __call__(self, key: str, text: str) -> None:
        self.reports.append((key, text))


def make(max_backlog: int = 0) -> tuple[StreamJoin, Sink]:
    sink = Sink()
    return StreamJoin("haar", SPR, max_backlog, SampleSequencer(SPR), sink), sink


def feed(join: StreamJoin, events, now: float = 0.0) -> list:
    out = []
    for kind, n in events:
        if kind == "m":
            m, s = meas(n)
            out += join.measurement(m, s, now, TIMEOUT)
        else:
            out += join.coefficients(coeffs(n), now, TIMEOUT)
    return out


def pairs(released) -> list[tuple[int, int | None]]:
    return [(m.sample_index, None if c is None else c.sample_index) for m, c in released]


def test_every_delivery_order_gives_the_samples_in_order_each_with_its_coefficients() -> None:
    n_samples = 3 * SPR
    expected = [(n, n if n % 2 else None) for n in range(n_samples)]
    rng = random.Random(7)
    for _ in range(50):
        # each topic in order (as DDS delivers it), the two interleaved at random
        ms = [("m", n) for n in range(n_samples)]
        cs = [("c", n) for n in range(1, n_samples, 2)]
        events = []
        while ms or cs:
            source = ms if (ms and (not cs or rng.random() < 0.5)) else cs
            events.append(source.pop(0))
        join, sink = make()
        assert pairs(feed(join, events)) == expected
        assert join.waiting == 0 and sink.reports == []
        assert join.counts == dict.fromkeys(join.counts, 0)


def test_an_odd_sample_waits_for_its_coefficients_until_the_stream_is_silent_for_timeout() -> None:
    join, _ = make()
    assert pairs(feed(join, [("m", 0), ("m", 1), ("m", 2)], now=10.0)) == [(0, None)]
    # not before the timeout, counted from the measurement's arrival
    assert join.release(10.0 + 0.5 * TIMEOUT, TIMEOUT) == []
    assert pairs(join.release(10.0 + 1.5 * TIMEOUT, TIMEOUT)) == [(1, None), (2, None)]
    assert join.counts["coefficients_missing"] == 1


def test_the_timeout_counts_from_the_last_coefficient_message_before_the_sample() -> None:
    join, _ = make()
    feed(join, [("m", n) for n in range(4)], now=0.0)
    assert pairs(join.coefficients(coeffs(1), 0.9 * TIMEOUT, TIMEOUT)) == [(1, 1), (2, None)]
    # sample 3 arrived at 0 s, but the stream progressed at 0.9 timeout: still waiting at 1.5
    assert join.release(1.5 * TIMEOUT, TIMEOUT) == []
    assert pairs(join.release(2.0 * TIMEOUT, TIMEOUT)) == [(3, None)]


def test_a_later_message_within_two_periods_means_the_sample_s_own_was_lost() -> None:
    join, _ = make()
    assert pairs(feed(join, [("m", n) for n in range(6)])) == [(0, None)]
    released = join.coefficients(coeffs(3), 0.0, TIMEOUT)  # 1's never comes
    assert pairs(released) == [(1, None), (2, None), (3, 3), (4, None)]
    assert join.counts["coefficients_missing"] == 1


def test_a_message_far_beyond_the_sample_is_no_progress_towards_it() -> None:
    join, _ = make()
    assert pairs(feed(join, [("m", n) for n in range(2)])) == [(0, None)]
    far = 1 + 2 * SPR + 2  # beyond two periods after sample 1, within the horizon
    assert join.coefficients(coeffs(far), 0.5 * TIMEOUT, TIMEOUT) == []
    # the far message does not restart the wait: its sample lies after 1
    assert pairs(join.release(1.01 * TIMEOUT, TIMEOUT)) == [(1, None)]


def test_refused_coefficients_are_counted_reported_and_release_nothing() -> None:
    join, sink = make()
    feed(join, [("m", 0), ("m", 1), ("c", 1), ("m", 2), ("m", 3)])
    cases = [
        (coeffs(3, wavelet="db4"), "'db4' at 16 samples/rev, expected 'haar'"),
        (coeffs(3, samples_per_rev=32), "at 32 samples/rev"),
        (coeffs(1), "sample 2 already processed"),
        (coeffs(3 + COEFFICIENT_HORIZON_PERIODS * SPR + 2), "from the future"),
    ]
    for i, (msg, words) in enumerate(cases, start=1):
        assert join.coefficients(msg, 0.0, TIMEOUT) == []
        assert join.counts["coefficients_rejected"] == i
        key, text = sink.reports[-1]
        assert key == "coefficients_rejected" and words in text, text
    assert join.waiting == 1  # sample 3 still waits for its own
    join.reject("unreadable coefficients: truncated; dropped")  # the node's own refusals
    assert join.counts["coefficients_rejected"] == len(cases) + 1
    assert sink.reports[-1] == (
        "coefficients_rejected",
        "unreadable coefficients: truncated; dropped",
    )


def test_coefficients_with_another_stamp_are_dropped_and_the_sample_goes_without() -> None:
    join, sink = make()
    feed(join, [("m", 0), ("m", 1)])
    wrong = Coeffs(1, stamp_of(1, t0=0.5))
    assert pairs(join.coefficients(wrong, 0.0, TIMEOUT)) == [(1, None)]
    assert join.counts["coefficients_rejected"] == 1
    assert "stamp differs" in sink.reports[-1][1]


def test_a_repeated_coefficient_message_is_refused() -> None:
    join, sink = make()
    feed(join, [("m", 0), ("c", 3)])
    assert join.coefficients(coeffs(3), 0.0, TIMEOUT) == []
    assert "repeated" in sink.reports[-1][1]


def test_a_restart_releases_the_old_stream_s_tail_first() -> None:
    join, sink = make()
    feed(join, [("m", n) for n in range(4)] + [("c", 1)])
    assert join.waiting == 1  # sample 3 waits for its coefficients
    # the stream restarts at 0 (a restarted plant): confirmed by its second sample
    out = []
    for n in (0, 1):
        m, s = meas(n, t0=100.0)
        out += join.measurement(m, s, 0.0, TIMEOUT)
    assert pairs(out) == [(3, None), (0, None)]
    assert join.sequencer.counts["restart"] == 1
    assert sink.reports[-1][0] == "sequence" and "restart" in sink.reports[-1][1]


def test_beyond_max_backlog_the_oldest_measurements_are_dropped_and_counted() -> None:
    join, sink = make(max_backlog=4)
    # no coefficients come: 0 goes at once, 1 waits; at 5 the queue 1..5 passes 4, so 1 is
    # dropped and 2 goes; at 7 the same for 3 and 4
    released = feed(join, [("m", n) for n in range(8)])
    assert pairs(released) == [(0, None), (2, None), (4, None)]
    assert join.waiting == 3 and join.counts["pending_dropped"] == 2
    assert sink.reports[-1][0] == "pending" and "the oldest 1 dropped" in sink.reports[-1][1]
    assert pairs(join.release(0.0, TIMEOUT, force=True)) == [(5, None), (6, None), (7, None)]
