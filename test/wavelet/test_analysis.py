"""Causal analysis filterbank against PyWavelets, streaming against block."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import pywt

from amb_wavelet.analysis import AnalysisFilterbank, analyze_block
from amb_wavelet.errors import LevelError, SampleIndexError
from amb_wavelet.levels import support_length

#: Wavelets the issue names for the PyWavelets equality tests.
WAVELETS = ("haar", "db2", "db4", "sym4", "coif2")


@pytest.mark.parametrize("wavelet", WAVELETS)
@pytest.mark.parametrize("level", range(1, 9))
@pytest.mark.parametrize("kind", ["random", "sinusoid"])
def test_block_equals_pywt_wavedec_zero_mode(
    rng: np.random.Generator, make_signals, wavedec_zero, wavelet: str, level: int, kind: str
) -> None:
    x = make_signals(rng, n=300)[kind]
    dec = analyze_block(x, wavelet, level)
    ref = wavedec_zero(x, wavelet, level)
    scale = np.max(np.abs(x))
    for j in range(1, level + 1):
        got = dec.details[j - 1]
        assert got.shape == (300 // 2**j, 3)
        np.testing.assert_allclose(
            got, ref[level - j + 1][: got.shape[0]], rtol=0, atol=1e-12 * scale
        )
    got = dec.approximation
    np.testing.assert_allclose(got, ref[0][: got.shape[0]], rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("wavelet", WAVELETS)
def test_level_one_equals_pywt_dwt(rng: np.random.Generator, wavelet: str) -> None:
    x = rng.standard_normal(257)
    cA, cD = pywt.dwt(x, wavelet, mode="zero")
    dec = analyze_block(x, wavelet, 1)
    np.testing.assert_allclose(dec.details[0], cD[:128], rtol=0, atol=1e-12)
    np.testing.assert_allclose(dec.approximation, cA[:128], rtol=0, atol=1e-12)


def _records_to_arrays(records, level: int, n_channels: int):
    details = {j: {} for j in range(1, level + 1)}
    approx = {}
    for r in records:
        target = details[r.level] if r.kind == "detail" else approx
        assert r.translation_index not in target
        target[r.translation_index] = r.values
    as_array = lambda d: np.array([d[m] for m in sorted(d)]).reshape(-1, n_channels)  # noqa: E731
    return [as_array(details[j]) for j in range(1, level + 1)], as_array(approx)


@pytest.mark.parametrize("wavelet", WAVELETS)
@pytest.mark.parametrize("level", [1, 3, 8])
def test_streaming_equals_block_and_pywt(
    rng: np.random.Generator, make_signals, wavedec_zero, wavelet: str, level: int
) -> None:
    x = make_signals(rng, n=300)["sinusoid"]
    bank = AnalysisFilterbank(wavelet, level, 3)
    records = [r for i, row in enumerate(x) for r in bank.step(row, sample_index=i)]
    details, approx = _records_to_arrays(records, level, 3)
    ref = wavedec_zero(x, wavelet, level)
    for j in range(1, level + 1):
        m = 300 // 2**j
        np.testing.assert_allclose(details[j - 1], ref[level - j + 1][:m], rtol=0, atol=1e-16)
    np.testing.assert_allclose(approx, ref[0][: 300 // 2**level], rtol=0, atol=1e-16)


@pytest.mark.parametrize("wavelet", ["haar", "db4"])
def test_chunked_equals_batch(rng: np.random.Generator, wavelet: str) -> None:
    """Model: scipy.signal tests (lfilter with zi): any chunking gives the same numbers."""
    level = 5
    x = rng.standard_normal((517, 4))
    batch = analyze_block(x, wavelet, level)
    bank = AnalysisFilterbank(wavelet, level, 4)
    cuts = np.sort(rng.choice(np.arange(1, 517), size=40, replace=False))
    pieces = [bank.process_block(c) for c in np.split(x, cuts)]
    for j in range(level):
        got = np.concatenate([p.details[j] for p in pieces])
        np.testing.assert_allclose(got, batch.details[j], rtol=0, atol=1e-13)
        assert pieces[0].translation_start[j] == 0
        # each piece continues where the previous one ended
        for a, b in itertools.pairwise(pieces):
            assert b.translation_start[j] == a.translation_start[j] + a.details[j].shape[0]
    got = np.concatenate([p.approximation for p in pieces])
    np.testing.assert_allclose(got, batch.approximation, rtol=0, atol=1e-13)


def test_mixed_step_and_block(rng: np.random.Generator) -> None:
    x = rng.standard_normal((100, 2))
    batch = analyze_block(x, "db2", 3)
    bank = AnalysisFilterbank("db2", 3, 2)
    recs = [r for row in x[:13] for r in bank.step(row)]
    rest = bank.process_block(x[13:])
    lvl3 = [r.values for r in recs if r.level == 3 and r.kind == "detail"]
    got = np.concatenate([np.array(lvl3).reshape(-1, 2), rest.details[2]])
    np.testing.assert_allclose(got, batch.details[2], rtol=0, atol=1e-13)


def test_record_timing_and_support() -> None:
    bank = AnalysisFilterbank("db4", 3, 1)
    L = 8
    records = [(n, r) for n in range(64) for r in bank.step([0.0])]
    for n, r in records:
        assert r.last_sample_index == n == 2**r.level * (r.translation_index + 1) - 1
        assert r.last_sample_index - r.first_sample_index + 1 == (2**r.level - 1) * (L - 1) + 1
        assert r.settled == (r.first_sample_index >= 0)
    kinds = [(r.level, r.kind) for n, r in records if n == 7]
    assert kinds == [(1, "detail"), (2, "detail"), (3, "detail"), (3, "approximation")]
    assert support_length(3, L) == 50


def test_support_is_what_the_coefficient_depends_on(rng: np.random.Generator) -> None:
    """An impulse inside the support changes the coefficient; one just outside does not."""
    level, wavelet = 3, "db2"
    n = 96
    base = analyze_block(np.zeros(n), wavelet, level).details[level - 1]
    m = 7
    last = 2**level * (m + 1) - 1
    first = last - support_length(level, 4) + 1
    for k, inside in [(first - 1, False), (first, True), (last, True), (last + 1, False)]:
        x = np.zeros(n)
        x[k] = 1.0
        d = analyze_block(x, wavelet, level).details[level - 1]
        assert (abs(d[m] - base[m]) > 1e-12) == inside, k


def test_reset_restarts_on_the_absolute_grid(rng: np.random.Generator, wavedec_zero) -> None:
    """After reset at index s the output equals the transform of x with zeros before s."""
    x = rng.standard_normal((200, 2))
    s = 77
    bank = AnalysisFilterbank("db2", 4, 2)
    bank.process_block(x[:50])
    bank.reset(start_sample_index=s)
    recs = [r for i in range(s, 200) for r in bank.step(x[i], sample_index=i)]
    xz = x.copy()
    xz[:s] = 0.0
    ref = wavedec_zero(xz, "db2", 4)
    for r in recs:
        expected = ref[4 - r.level + 1] if r.kind == "detail" else ref[0]
        np.testing.assert_allclose(r.values, expected[r.translation_index], rtol=0, atol=1e-13)
        assert r.settled == (r.first_sample_index >= s)
    assert any(r.settled for r in recs) and any(not r.settled for r in recs)


def test_sample_index_gap_raises_and_keeps_state() -> None:
    bank = AnalysisFilterbank("haar", 2, 1)
    bank.step([1.0], sample_index=0)
    with pytest.raises(SampleIndexError, match="expected 1") as info:
        bank.step([1.0], sample_index=3)
    assert (info.value.expected, info.value.actual) == (1, 3)
    assert bank.next_sample_index == 1
    recs = bank.step([1.0], sample_index=1)
    assert recs[0].values[0] == pytest.approx(0.0, abs=1e-15)  # haar detail of [1, 1]


@pytest.mark.parametrize("level", [0, -1, 2.5, "3"])
def test_bad_level(level) -> None:
    with pytest.raises(LevelError, match="level"):
        AnalysisFilterbank("haar", level, 1)


def test_bad_shapes() -> None:
    bank = AnalysisFilterbank("haar", 2, 3)
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        bank.step([1.0, 2.0])
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        bank.process_block(np.zeros((4, 2)))
