"""The age rule of the realtime catch-up (:class:`amb_tools.backlog.MessageAge`), without DDS.

A writer publishes every ``DT`` (its wall clock; the DDS source timestamp) and the reader takes
each message ``LATENCY`` later on its own clock, which may be offset from the writer's. The
reader sees the timestamps and the writer's sequence numbers only of the runs it takes after
the executor's message, so a reader keeping up is modelled by pairs of consecutive messages. A
message is too old when its age less the stream's smallest age exceeds ``BOUND`` intervals; the
references are those closed forms on exact integer nanoseconds.
"""

from __future__ import annotations

import pytest

from amb_common.topics import SAMPLES_PER_COEFFICIENT_MESSAGE
from amb_tools.backlog import NO_CATCH_UP, CatchUp, MessageAge

DT = 1_000_000  # ns between publishes (1 kHz)
LATENCY = 200_000  # ns from publish to take when the reader keeps up
BOUND = 128  # messages


def _pairs(age: MessageAge, count: int, offset: int = 0, start: int = 0, dt: int = DT) -> int:
    """Feed ``count`` runs of two consecutive messages taken as the second arrives (message k is
    the writer's k-th publish)."""
    old = 0
    for k in range(start, start + 2 * count, 2):
        sent = [k * dt, (k + 1) * dt]
        old += age.old(sent, sent[-1] + LATENCY + offset, sequence=[k, k + 1])
    return old


@pytest.mark.parametrize("offset", [0, 5_000_000_000, -3_000_000_000])
def test_a_reader_that_keeps_up_drops_nothing_whatever_the_clock_offset(offset: int) -> None:
    age = MessageAge(BOUND)
    assert _pairs(age, 1000, offset) == 0
    assert age.limit_s == pytest.approx(BOUND * DT * 1e-9, rel=1e-12)


@pytest.mark.parametrize("offset", [0, 5_000_000_000])
def test_a_trickle_after_a_stall_is_dropped_up_to_the_bound(offset: int) -> None:
    """Runs of 10 taken 1 s after their publish, then faster: old while beyond the bound."""
    age = MessageAge(BOUND)
    _pairs(age, 250, offset)  # messages 0..499
    released = 500 * DT + 1_000_000_000  # ns, the reader is let go 1 s after message 500
    got, expected = [], []
    for j, first in enumerate(range(500, 1600, 10)):
        sent = [k * DT for k in range(first, first + 10)]
        now = released + j * 1_000_000 + LATENCY  # one run of 10 per ms: it catches up
        got.append(age.old(sent, now + offset, sequence=list(range(first, first + 10))))
        # ages less the floor (LATENCY): now - LATENCY - k DT; old while > BOUND DT
        expected.append(sum(now - LATENCY - t > BOUND * DT for t in sent))
    assert got == expected
    assert got[0] == 10 and got[-1] == 0  # the rule both drops and stops dropping here


def test_a_run_is_old_up_to_its_last_message_beyond_the_bound() -> None:
    age = MessageAge(BOUND)
    _pairs(age, 250)  # messages 0..499
    now = 700 * DT + LATENCY  # the reader wakes late with messages 500..699 queued
    sent = [k * DT for k in range(500, 700)]
    # ages less the floor (LATENCY): (700 - k) DT; old when > BOUND DT, i.e. k < 700 - BOUND
    assert age.old(sent, now, sequence=list(range(500, 700))) == 700 - BOUND - 500


def test_no_age_bound_before_a_span_of_max_backlog_publishes() -> None:
    age = MessageAge(BOUND)
    assert age.old([], 10**12, sequence=[]) == 0  # the executor's message alone: nothing known
    assert age.old([0], 10**12, sequence=[0]) == 0  # one message: no spacing yet
    # runs of two taken on time: the span reaches BOUND - 2 publishes, not yet
    for first in range(2, BOUND - 2, 3):
        run = [first * DT, (first + 1) * DT]
        assert age.old(run, run[-1] + LATENCY, sequence=[first, first + 1]) == 0
    assert age.limit_s == float("inf")
    # one 1 s late, its span BOUND - 1 publishes: not yet
    late = [(BOUND - 2) * DT, (BOUND - 1) * DT]
    assert age.old(late, late[-1] + 10**9, sequence=[BOUND - 2, BOUND - 1]) == 0
    # the run that completes the first span is judged with the new estimate
    late = [BOUND * DT, (BOUND + 1) * DT]
    assert age.old(late, late[-1] + 10**9, sequence=[BOUND, BOUND + 1]) == 2
    assert age.limit_s == pytest.approx(BOUND * DT * 1e-9, rel=1e-12)


def test_a_start_up_burst_shrinks_the_bound_only_until_the_second_span() -> None:
    """The realtime plant starts late and releases its first 100 samples at once, then one per
    DT: the span holding the burst is short (29 DT over 128 publishes); the larger of two spans,
    then the median of three, are not."""
    age = MessageAge(BOUND)
    burst = 100
    sent = [(burst - 1) * DT + k * 1_000 for k in range(burst)]  # at 99 DT, 1 us apart
    age.old(sent, sent[-1] + LATENCY, sequence=list(range(burst)))
    for k in range(burst, burst + 6 * BOUND, 2):
        run = [k * DT, (k + 1) * DT]
        assert age.old(run, run[-1] + LATENCY, sequence=[k, k + 1]) == 0
        if k == BOUND:  # the first span, over the burst
            assert age.interval_s == pytest.approx((BOUND - burst + 1) / BOUND * DT * 1e-9)
        if k >= 2 * BOUND:  # two spans and more
            assert age.interval_s == pytest.approx(DT * 1e-9, rel=1e-12), k


def test_a_writer_publishing_in_bursts_is_measured_at_its_mean_rate() -> None:
    """A realtime plant whose timer fires every 4 DT releases 4 samples within 3 us, and the
    reader takes its runs of two inside the bursts: the spacings it sees are 1 us, the writer's
    rate is one per DT. (Estimated from the spacings within the runs, the bound was 2-42 ms
    instead of 182 ms in the overload test.)"""
    age = MessageAge(BOUND)
    burst = 4
    for b in range(200):
        seq = [burst * b + 2, burst * b + 3]
        sent = [burst * b * DT + 1_000 * j for j in (2, 3)]
        assert age.old(sent, sent[-1] + LATENCY, sequence=seq) == 0
    # the span's ends are both within a burst: off by at most 3 us over >= BOUND publishes
    assert age.interval_s == pytest.approx(DT * 1e-9, rel=3_000 / (BOUND * DT))


def test_messages_the_reader_never_received_do_not_move_the_interval() -> None:
    """The reader's queue overflowed in a stall: the writer's numbers skip 700, its stamps
    still advance one DT per publish, and the estimate stays DT (the publishes are counted, not
    the messages received)."""
    age = MessageAge(BOUND)
    _pairs(age, 250)  # messages 0..499
    seq = [1200, 1201]
    sent = [k * DT for k in seq]
    age.old(sent, sent[-1] + LATENCY, sequence=seq)
    assert age.interval_s == pytest.approx(DT * 1e-9, rel=1e-12)


def test_a_restarted_writer_is_estimated_afresh() -> None:
    """The sequence numbers start again: no bound until a span of the new writer is seen."""
    age = MessageAge(BOUND)
    _pairs(age, 250)  # messages 0..499 at DT
    t0 = 10**12
    assert age.old([t0, t0 + DT // 2], t0 + 10**9, sequence=[1, 2]) == 0
    assert age.limit_s == float("inf")


def test_a_pause_of_the_writer_does_not_stretch_the_bound() -> None:
    """The writer stops for 1 s (a filterbank stopped with its reader): one span holds the
    pause, the median of the last three does not."""
    age = MessageAge(BOUND)
    _pairs(age, 250)  # messages 0..499 at DT
    pause = 1_000_000_000
    for k in range(500, 500 + 2 * BOUND, 2):
        sent = [k * DT + pause, (k + 1) * DT + pause]
        assert age.old(sent, sent[-1] + LATENCY, sequence=[k, k + 1]) == 0
        assert age.interval_s == pytest.approx(DT * 1e-9, rel=1e-12)


def test_a_speed_change_is_followed_within_three_spans() -> None:
    """The writer's rate doubles (a run-up): after 3 spans at the new rate, two of the last
    three spans hold only it, and the interval is the new one."""
    age = MessageAge(BOUND)
    _pairs(age, 250)  # messages 0..499 at DT
    assert _pairs(age, 3 * BOUND // 2, start=1000, dt=DT // 2) == 0
    assert age.interval_s == pytest.approx(DT / 2 * 1e-9, rel=1e-12)


def test_a_bound_below_one_is_refused() -> None:
    with pytest.raises(ValueError, match="max_backlog = 0"):
        MessageAge(0)


def test_a_coefficient_reader_is_bounded_by_the_same_time_behind() -> None:
    """One coefficient message per two samples: half as many messages, the same samples."""
    assert CatchUp(128).per_message(SAMPLES_PER_COEFFICIENT_MESSAGE) == CatchUp(64)
    assert CatchUp(1, by_age=False).per_message(2) == CatchUp(1, by_age=False)  # at least 1
    assert NO_CATCH_UP.per_message(2) == NO_CATCH_UP  # lockstep keeps every message
    with pytest.raises(ValueError, match="samples per message = 0"):
        CatchUp(128).per_message(0)
