"""ThrottledWarnings: one printed warning per period and key, the held-back ones counted."""

from __future__ import annotations

import pytest

from amb_tools.throttled_log import ThrottledWarnings


class _Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


class _Lines:
    """Collects what would go to a node's logger."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def warning(self, text: str) -> None:
        self.lines.append(text)


def test_one_warning_per_period_and_key_with_the_held_back_count() -> None:
    clock, out = _Clock(), _Lines()
    warn = ThrottledWarnings(out, period=5.0, clock=clock)
    assert warn.warning("gap", "sample 10 after 7: gap")
    clock.t += 1.0
    assert not warn.warning("gap", "sample 20 after 17: gap")
    assert warn.warning("stray", "sample 30 after 25: not confirmed")  # another key: printed
    clock.t += 3.0
    assert not warn.warning("gap", "sample 40 after 37: gap")
    assert warn.held("gap") == 2
    clock.t += 1.0  # 5 s after the first gap warning
    assert warn.warning("gap", "sample 50 after 47: gap")
    assert warn.held("gap") == 0
    assert out.lines == [
        "sample 10 after 7: gap",
        "sample 30 after 25: not confirmed",
        "sample 50 after 47: gap (2 more like it in the last 5.0 s)",
    ]


def test_period_zero_prints_everything_and_a_negative_period_is_refused() -> None:
    out = _Lines()
    warn = ThrottledWarnings(out, period=0.0, clock=_Clock())
    assert warn.warning("k", "a") and warn.warning("k", "b")
    assert out.lines == ["a", "b"]
    with pytest.raises(ValueError, match="period"):
        ThrottledWarnings(out, period=-1.0)
