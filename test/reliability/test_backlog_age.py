"""The age rule of the realtime catch-up (:class:`amb_tools.backlog.MessageAge`), without DDS.

A writer publishes every ``DT`` (its wall clock; the DDS source timestamp) and the reader takes
each message ``LATENCY`` later on its own clock, which may be offset from the writer's. The
reader sees the timestamps only of the runs it takes after the executor's message, so a
reader keeping up is modelled by pairs of consecutive messages. A message is too old when its
age less the stream's smallest age exceeds ``BOUND`` intervals; the references are those closed
forms on exact integer nanoseconds.
"""

from __future__ import annotations

import pytest

from amb_tools.backlog import MessageAge

DT = 1_000_000  # ns between publishes (1 kHz)
LATENCY = 200_000  # ns from publish to take when the reader keeps up
BOUND = 128  # messages


def _pairs(age: MessageAge, count: int, offset: int = 0, start: int = 0, dt: int = DT) -> int:
    """Feed ``count`` runs of two consecutive messages taken as the second arrives."""
    old = 0
    for k in range(start, start + 2 * count, 2):
        sent = [k * dt, (k + 1) * dt]
        old += age.old(sent, sent[-1] + LATENCY + offset)
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
        got.append(age.old(sent, now + offset))
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
    assert age.old(sent, now) == 700 - BOUND - 500


def test_no_age_bound_before_the_interval_is_known() -> None:
    age = MessageAge(BOUND)
    warmup = MessageAge.WARMUP
    assert age.old([], 10**12) == 0  # the executor's message alone: nothing known
    assert age.old([0], 10**12) == 0  # one message: no spacing yet
    _pairs(age, warmup - 2, start=2)  # WARMUP - 2 spacings: not yet
    assert age.limit_s == float("inf")
    k = 2 * warmup
    late = [k * DT, (k + 1) * DT]  # the WARMUP-1-th spacing, 1 s late: not yet
    assert age.old(late, late[-1] + 10**9) == 0
    # the run bringing the WARMUP-th spacing, 1 s late, is judged with the new estimate
    late = [(k + 2) * DT, (k + 3) * DT]
    assert age.old(late, late[-1] + 10**9) == 2
    assert age.limit_s == pytest.approx(BOUND * DT * 1e-9, rel=1e-12)


def test_a_gap_or_a_burst_of_the_writer_moves_the_interval_by_one_bound_at_most() -> None:
    """The writer lost 144 messages within a run, then published 50 at once."""
    age = MessageAge(BOUND)
    _pairs(age, 250)  # messages 0..499
    gap = [500 * DT, 644 * DT]
    assert age.old(gap, gap[-1] + LATENCY) == 1  # message 500 is 144 intervals old
    # the 144 DT spacing counts as 2 DT: the estimate moves by DT / BOUND
    after_gap = DT * (1 + 1 / BOUND)
    assert age.interval_s == pytest.approx(after_gap * 1e-9, rel=1e-12)
    burst = [900 * DT + k for k in range(50)]  # 1 ns apart
    assert age.old(burst, burst[-1] + LATENCY) == 0
    # each of the 49 spacings of 1 ns counts as half the estimate
    after_burst = after_gap * (1 - 0.5 / BOUND) ** 49
    assert age.interval_s == pytest.approx(after_burst * 1e-9, rel=1e-12)
    assert after_burst > 0.8 * DT


def test_a_speed_change_is_followed_within_a_few_bounds() -> None:
    """The writer's rate doubles (a run-up): the interval halves within 4 BOUND spacings."""
    age = MessageAge(BOUND)
    _pairs(age, 250)  # messages 0..499 at DT
    assert _pairs(age, 4 * BOUND, start=1000, dt=DT // 2) == 0
    assert age.interval_s == pytest.approx(DT / 2 * 1e-9, rel=0.02)


def test_a_bound_below_one_is_refused() -> None:
    with pytest.raises(ValueError, match="max_backlog = 0"):
        MessageAge(0)
