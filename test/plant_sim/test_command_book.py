"""The plant's command rules (``amb_plant_sim.node`` docstring, ARCHITECTURE.md "Time"), ROS-free.

Period ``k`` covers samples ``k N .. k N + N - 1``; a command for ``k`` answers measured period
``k - i``. Each rule below is written out by hand from the node's documentation.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from amb_plant_sim.command_book import COMMAND_HORIZON_PERIODS, CommandBook, CommandOffer

N = 8
DELAY = 2
LIMIT = 1000.0


def offer(k: int, *, value: float = 1.0, delay: int = DELAY, based_on: int | None = None,
          stamp: float = 0.0, malformed: str | None = None) -> CommandOffer:  # fmt: skip
    force = None if malformed else np.full((N, 4), value)
    based = k - delay if based_on is None else based_on
    return CommandOffer(k, delay, based, stamp, force, malformed)


def test_a_command_in_time_is_applied_to_its_period_and_older_ones_are_forgotten() -> None:
    book = CommandBook(DELAY, LIMIT, realtime=False)
    assert book.offer(offer(5, value=2.0), next_period=5, last_stamp=1.0, now=0.0) is None
    assert book.offer(offer(6, value=3.0), next_period=5, last_stamp=1.0, now=0.0) is None
    assert 5 in book and 6 in book
    assert book.take(4) is None  # no command for period 4
    assert book.take(6)[0, 0] == 3.0  # period 5 never started: its command goes with it
    assert 5 not in book
    assert book.counts["applied"] == 1 and book.counts["rejected"] == book.counts["late"] == 0


def test_a_command_for_a_started_period_is_late_and_its_lateness_kept_in_realtime() -> None:
    book = CommandBook(DELAY, LIMIT, realtime=True)
    assert book.take(7, now=100.0) is None
    reason = book.offer(offer(7), next_period=8, last_stamp=1.0, now=100.004)
    assert "arrived after it started" in reason
    assert book.counts["late"] == 1 and book.counts["rejected"] == 0
    assert book.control_summary(periods=8)["arrival_max"] == pytest.approx(0.004, abs=1e-9)
    # a late command that is also malformed counts once, as late
    assert book.offer(offer(6, malformed="bad"), 8, 1.0, 100.01) is not None
    assert book.counts["late"] == 2 and book.counts["rejected"] == 0


@pytest.mark.parametrize(
    ("made", "words"),
    [
        (offer(5, malformed="force has 3 values, expected 32"), "force has 3 values"),
        (offer(5, delay=1), "made with delay_periods 1, the plant runs 2"),
        (offer(5, based_on=4), "based on period 4, only 3 measured: from the future"),
        (offer(5, stamp=1.5), "after the last sample"),
        (offer(4 + DELAY + COMMAND_HORIZON_PERIODS + 1), "is not plausible"),
    ],
)
def test_refused_commands_are_counted_and_named(made: CommandOffer, words: str) -> None:
    book = CommandBook(DELAY, LIMIT, realtime=False)
    reason = book.offer(made, next_period=4, last_stamp=1.0, now=0.0)
    assert words in reason
    assert book.counts["rejected"] == 1 and made.period_index not in book


def test_the_horizon_admits_its_last_period() -> None:
    book = CommandBook(DELAY, LIMIT, realtime=False)
    last = offer(4 + DELAY + COMMAND_HORIZON_PERIODS, based_on=3)
    assert book.offer(last, 4, 1.0, 0.0) is None


def test_a_repeated_command_is_refused_and_the_first_kept() -> None:
    book = CommandBook(DELAY, LIMIT, realtime=False)
    assert book.offer(offer(5, value=1.0), 4, 1.0, 0.0) is None
    assert "repeated" in book.offer(offer(5, value=9.0), 4, 1.0, 0.0)
    assert np.all(book.take(5) == 1.0)


def test_a_force_beyond_the_limit_is_clipped_to_it_and_counted() -> None:
    book = CommandBook(DELAY, 100.0, realtime=False)
    made = offer(5)
    made.force[3, 1], made.force[4, 2] = 250.0, -400.0
    assert book.offer(made, 4, 1.0, 0.0) is None
    f = book.take(5)
    assert f[3, 1] == 100.0 and f[4, 2] == -100.0 and f[0, 0] == 1.0
    assert book.counts["clipped"] == 1


def test_latency_runs_from_a_periods_last_sample_to_the_command_based_on_it() -> None:
    book = CommandBook(DELAY, LIMIT, realtime=True)
    for m, lag in ((3, 0.002), (4, 0.006), (5, 0.004)):
        book.period_sent(m, now=10.0 + m)
        assert book.offer(offer(m + DELAY), m + 1, 1.0, now=10.0 + m + lag) is None
    lat = book.latency_summary()
    assert lat["n"] == 3
    assert lat["p50"] == pytest.approx(0.004, abs=1e-9)
    assert lat["max"] == pytest.approx(0.006, abs=1e-9)


def test_control_summary_counts_the_periods_that_could_have_a_command() -> None:
    book = CommandBook(DELAY, LIMIT, realtime=True)
    assert math.isnan(book.control_summary(periods=DELAY)["controlled"])
    for k in range(DELAY, DELAY + 4):  # four periods in time, by 5 ms each
        assert book.offer(offer(k), k - 1, 1.0, now=k - 0.005) is None
        assert book.take(k, now=float(k)) is not None
    for k in range(DELAY + 4, DELAY + 8):  # four without a command
        assert book.take(k, now=float(k)) is None
    summary = book.control_summary(periods=DELAY + 8)
    assert summary["controlled"] == 0.5
    assert summary["arrival_p50"] == pytest.approx(-0.005, abs=1e-9)


def test_a_command_that_arrives_during_its_period_acts_on_the_samples_still_ahead() -> None:
    book = CommandBook(DELAY, LIMIT, realtime=True, partial=True)
    assert book.take(5, now=50.0) is None  # period 5 starts without its command: open
    assert book.open_period == 5
    assert book.take_rest(5, 3) is None  # nothing arrived yet
    made = offer(5, value=2.0)
    made.force[:] = np.arange(N)[:, None] + np.arange(4)[None, :]  # a distinct value per sample
    reason = book.offer(made, next_period=6, last_stamp=1.0, now=50.002)
    assert "arrived after it started" in reason and "rest of its period" in reason
    assert book.counts["late"] == 1 and book.counts["partial"] == 0
    rest = book.take_rest(5, 3)
    np.testing.assert_array_equal(rest, made.force[3:])  # samples 3 .. N-1 of the command
    assert book.counts["partial"] == 1 and book.open_period is None
    assert book.take_rest(5, 4) is None  # taken once
    # a second copy of the command finds the period closed: late, not kept
    assert "rest of its period" not in book.offer(offer(5), 6, 1.0, 50.003)
    assert book.counts["late"] == 2 and book.counts["partial"] == 1
    # of the eligible periods DELAY .. 5 (4), none ran whole with a command; 5 ran (N - 3) / N
    summary = book.control_summary(periods=6)
    assert summary["controlled"] == 0.0
    assert summary["controlled_samples"] == pytest.approx((N - 3) / N / 4, rel=1e-12)
    assert summary["arrival_max"] == pytest.approx(0.003, abs=1e-9)


@pytest.mark.parametrize(
    "made",
    [
        offer(5, malformed="force has 3 values, expected 32"),
        offer(5, delay=1),
        offer(4),  # a period that is not the open one
    ],
)
def test_a_late_command_that_is_malformed_or_not_for_the_open_period_is_not_kept(made) -> None:
    book = CommandBook(DELAY, LIMIT, realtime=True, partial=True)
    book.take(5, now=50.0)
    assert "rest of its period" not in book.offer(made, 6, 1.0, 50.001)
    assert book.counts["late"] == 1
    assert book.take_rest(5, 2) is None and book.counts["partial"] == 0


def test_without_partial_or_in_lockstep_no_period_stays_open() -> None:
    for book in (
        CommandBook(DELAY, LIMIT, realtime=True, partial=False),
        CommandBook(DELAY, LIMIT, realtime=False, partial=True),
    ):
        book.take(5, now=50.0 if book.realtime else None)
        assert book.open_period is None
        assert "rest of its period" not in book.offer(offer(5), 6, 1.0, 50.001)
        assert book.take_rest(5, 2) is None
    book = CommandBook(DELAY, LIMIT, realtime=True, partial=True)
    book.take(DELAY - 1, now=1.0)  # before delay_periods no command can exist: not open
    assert book.open_period is None
