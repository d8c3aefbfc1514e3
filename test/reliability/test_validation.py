"""Validation helpers of ``amb_tools.conversions`` (no ROS): the rules every node applies.

References are constructed streams whose correct answer is known by construction: a
consecutive stream with stray messages inserted must come out exactly as the stream; a
confirmed discontinuity must come out with one reset at the right sample.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from amb_tools.conversions import MessageError, to_float_array
from amb_tools.validation import (
    STAMP_TOLERANCE,
    SampleSequencer,
    check_command,
    check_measurement,
    stamp_step_error,
)

SPR = 16
OMEGA = 2 * math.pi * 20.0
DT = 2 * math.pi / (SPR * OMEGA)  # s per sample: 1 / 320


def _feed(seq: SampleSequencer, items):
    out = []
    for index, stamp in items:
        out += seq.push(index, stamp, OMEGA, (index, stamp))
    return out


def test_consecutive_stream_passes_unchanged() -> None:
    seq = SampleSequencer(SPR)
    items = [(n, n * DT) for n in range(100)]
    out = _feed(seq, items)
    assert [p for _, p in out] == items
    assert [r for r, _ in out] == [True] + [False] * 99
    assert all(v == 0 for v in seq.counts.values())


def test_repeat_is_dropped_and_counted() -> None:
    seq = SampleSequencer(SPR)
    out = _feed(seq, [(0, 0.0), (1, DT), (1, DT), (2, 2 * DT)])
    assert [p[0] for _, p in out] == [0, 1, 2]
    assert seq.counts["repeat"] == 1


def test_confirmed_gap_resets_at_the_new_index() -> None:
    seq = SampleSequencer(SPR)
    items = [(n, n * DT) for n in range(10)] + [(n, n * DT) for n in range(13, 20)]
    out = _feed(seq, items)
    assert [p[0] for _, p in out] == [n for n, _ in items]
    resets = [p[0] for r, p in out if r]
    assert resets == [0, 13]
    assert seq.counts["gap"] == 1 and seq.counts["stray"] == 0


def test_a_gap_the_reader_made_is_accepted_at_once() -> None:
    """The reader dropped 10..12 to catch up: 13 is the stream's newest (it may be its last)."""
    seq = SampleSequencer(SPR)
    _feed(seq, [(n, n * DT) for n in range(10)])
    out = seq.push(13, 13 * DT, OMEGA, "13", gap_known=True)
    assert out == [(True, "13")]
    assert seq.counts["gap"] == 1 and seq.last_index == 13
    assert seq.push(14, 14 * DT, OMEGA, "14") == [(False, "14")]
    # unknown, the same jump waits for the next sample to confirm it
    held = SampleSequencer(SPR)
    _feed(held, [(n, n * DT) for n in range(10)])
    assert held.push(13, 13 * DT, OMEGA, "13") == []
    assert held.pending_index == 13 and held.counts["gap"] == 0


@pytest.mark.parametrize(
    ("index", "stamp"),
    [(5, 5 * DT), (13, 30 * DT)],  # a step back; a stamp from the future for three samples
)
def test_a_known_gap_is_still_checked(index: int, stamp: float) -> None:
    seq = SampleSequencer(SPR)
    _feed(seq, [(n, n * DT) for n in range(10)])
    assert seq.push(index, stamp, OMEGA, "x", gap_known=True) == []
    assert seq.counts["gap"] == 0 and seq.last_index == 9


def test_plant_restart_from_zero_is_confirmed() -> None:
    seq = SampleSequencer(SPR)
    items = [(n, n * DT) for n in range(50)] + [(n, n * DT) for n in range(5)]
    out = _feed(seq, items)
    assert [p[0] for r, p in out if r] == [0, 0]
    assert len(out) == 55 and seq.counts["restart"] == 1


@pytest.mark.parametrize(
    ("stamp", "word"),
    [(8 * DT, "before"), (10 * DT + 2 * STAMP_TOLERANCE * DT, "future")],
)
def test_impossible_stamps_are_rejected(stamp: float, word: str) -> None:
    seq = SampleSequencer(SPR)
    _feed(seq, [(n, n * DT) for n in range(10)])
    assert _feed(seq, [(10, stamp)]) == []
    assert seq.counts["stamp"] == 1 and word in seq.last_reason


def test_stamp_step_limits() -> None:
    assert stamp_step_error(1.0, 1.0, 1, OMEGA, SPR) is None  # equal stamps allowed
    assert stamp_step_error(1.0, 1.0 + 3 * DT, 1, OMEGA, SPR) is None
    assert "future" in stamp_step_error(1.0, 1.0 + 5 * DT, 1, OMEGA, SPR)
    assert stamp_step_error(1.0, 1.0 + 5 * DT, 2, OMEGA, SPR) is None
    assert "before" in stamp_step_error(1.0, 1.0 - 1e-9, 1, OMEGA, SPR)


@settings(max_examples=60, deadline=None)
@given(
    length=st.integers(20, 200),
    strays=st.lists(
        st.tuples(st.integers(1, 199), st.integers(0, 2**62), st.floats(-1e6, 1e6)),
        max_size=15,
    ),
)
def test_isolated_strays_never_derail_the_stream(length, strays) -> None:
    """Random stray messages between the samples of a real stream: the stream comes out whole.

    A stray that happens to equal the next index is the next sample's forgery; it is skipped
    when building the case (isolated strays only: a real stream's next sample follows each).
    """
    items = [(n, 100.0 + n * DT) for n in range(length)]
    positions = {}
    for pos, index, stamp in strays:
        if pos < length and abs(index - pos) > 1 and index != pos - 1:
            positions[pos] = (index, stamp)
    stream = []
    for n, item in enumerate(items):
        if n in positions:
            stream.append(positions[n])
        stream.append(item)
    seq = SampleSequencer(SPR)
    out = _feed(seq, stream)
    assert [p for _, p in out] == items
    assert seq.counts["stray"] + seq.counts["stamp"] + seq.counts["repeat"] == len(positions)


def _measurement(**fields):
    m = SimpleNamespace(
        displacement=np.zeros(8),
        current=np.zeros(4),
        bearing_force=np.zeros(4),
        wavelet_force=np.zeros(4),
        samples_per_rev=SPR,
        rotor_speed=OMEGA,
        rotor_angle=0.5,
        sample_index=3,
    )
    for k, v in fields.items():
        setattr(m, k, v)
    return m


@pytest.mark.parametrize(
    ("fields", "word"),
    [
        ({"displacement": np.zeros(7)}, "'displacement' has 7 values, expected 8"),
        ({"current": np.array([0.0, np.nan, 0.0, 0.0])}, "'current' has 1 non-finite"),
        ({"bearing_force": np.full(4, np.inf)}, "'bearing_force' has 4 non-finite"),
        ({"samples_per_rev": 32}, "'samples_per_rev' = 32, expected 16"),
        ({"rotor_speed": 0.0}, "'rotor_speed' = 0.0"),
        ({"rotor_speed": math.nan}, "'rotor_speed' = nan"),
        ({"rotor_angle": 2 * math.pi}, "'rotor_angle'"),
        ({"displacement": np.full(8, 2.0)}, "reaches 2 m"),
    ],
)
def test_check_measurement_names_field_and_values(fields, word) -> None:
    with pytest.raises(MessageError, match=None) as info:
        check_measurement(_measurement(**fields), SPR)
    assert word in str(info.value)


def test_check_measurement_accepts_a_valid_sample() -> None:
    check_measurement(_measurement(), SPR)  # raises if not


def _command(**fields):
    c = SimpleNamespace(
        period_index=5,
        samples_per_period=SPR,
        start_sample_index=5 * SPR,
        based_on_period=3,
        force=to_float_array(np.arange(4 * SPR, dtype=float)),
    )
    for k, v in fields.items():
        setattr(c, k, v)
    return c


def test_check_command_returns_sample_major_force() -> None:
    f = check_command(_command(), SPR)
    assert f.shape == (SPR, 4)
    np.testing.assert_array_equal(f[:, 2], np.arange(2 * SPR, 3 * SPR))  # axis-major in msg


@pytest.mark.parametrize(
    ("fields", "word"),
    [
        ({"start_sample_index": 3}, "expected 16 / 80"),
        ({"samples_per_period": 8}, "samples_per_period 8"),
        ({"based_on_period": 5}, "based_on_period < period_index"),
        ({"force": to_float_array(np.zeros(10))}, "'force' has 10 values, expected 64"),
        ({"force": to_float_array(np.full(64, np.nan))}, "64 non-finite"),
    ],
)
def test_check_command_rejects(fields, word) -> None:
    with pytest.raises(MessageError) as info:
        check_command(_command(**fields), SPR)
    assert word in str(info.value)
