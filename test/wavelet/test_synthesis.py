"""Synthesis: perfect reconstruction with the documented delay, against PyWavelets."""

from __future__ import annotations

import numpy as np
import pytest
import pywt

from amb_wavelet.analysis import AnalysisFilterbank, Decomposition, analyze_block
from amb_wavelet.filters import get_filters
from amb_wavelet.synthesis import (
    SynthesisFilterbank,
    atom_time_centre,
    basis_function,
    synthesize_block,
)


def _delay(level: int, wavelet: str) -> int:
    # closed form, section 4.2.4 and amb_wavelet.levels.synthesis_delay docstring
    return (2**level - 1) * (pywt.Wavelet(wavelet).dec_len - 1)


def _tolerance(wavelet: str, level: int, scale: float) -> float:
    # PR holds to the orthonormality of PyWavelets' table (sym: ~1e-12), never looser
    # than 1e-12 for the tables that are orthonormal to rounding
    return max(1e-12, 20 * level * get_filters(wavelet).orthonormality_error) * scale


@pytest.mark.parametrize("wavelet", ["haar", "db2", "db4", "sym4", "coif2"])
@pytest.mark.parametrize("level", range(1, 9))
def test_perfect_reconstruction_block(rng: np.random.Generator, wavelet: str, level: int) -> None:
    D = _delay(level, wavelet)
    n = D + 300
    x = rng.standard_normal((n, 2))
    y = synthesize_block(analyze_block(x, wavelet, level), n_samples=n)
    tol = _tolerance(wavelet, level, np.max(np.abs(x)))
    np.testing.assert_allclose(y[D:], x[: n - D], rtol=0, atol=tol)
    np.testing.assert_allclose(y[:D], 0.0, rtol=0, atol=tol)
    if get_filters(wavelet).orthonormality_error < 1e-15:
        assert tol == 1e-12 * np.max(np.abs(x))


@pytest.mark.parametrize("wavelet", ["haar", "db4", "coif2"])
@pytest.mark.parametrize("level", [1, 4])
def test_streaming_round_trip(rng: np.random.Generator, wavelet: str, level: int) -> None:
    D = _delay(level, wavelet)
    n = D + 200
    x = rng.standard_normal((n, 3))
    ana = AnalysisFilterbank(wavelet, level, 3)
    syn = SynthesisFilterbank(wavelet, level, 3)
    assert syn.delay == D
    y = np.array([syn.step(ana.step(row)) for row in x])
    np.testing.assert_allclose(y[D:], x[: n - D], rtol=0, atol=1e-12 * np.max(np.abs(x)))
    block = synthesize_block(analyze_block(x, wavelet, level), n_samples=n)
    np.testing.assert_allclose(y, block, rtol=0, atol=1e-13)


@pytest.mark.parametrize("wavelet", ["haar", "db2", "db4", "coif2"])
@pytest.mark.parametrize("level", [1, 3, 6])
def test_arbitrary_coefficients_equal_pywt_waverec(
    rng: np.random.Generator, wavedec_zero, wavelet: str, level: int
) -> None:
    """Control coefficients chosen freely: synthesis is PyWavelets' waverec, delayed."""
    n = 256
    layout = wavedec_zero(np.zeros(n), wavelet, level)
    counts = [n // 2**level] + [n // 2**j for j in range(level, 0, -1)]
    coeffs = []
    for arr, m in zip(layout, counts, strict=True):
        c = np.zeros_like(arr)
        c[:m] = rng.standard_normal(m)
        coeffs.append(c)
    ref = pywt.waverec(coeffs, wavelet, mode="zero")
    dec = Decomposition(
        wavelet,
        tuple(coeffs[level - j + 1][: n // 2**j] for j in range(1, level + 1)),
        coeffs[0][: n // 2**level],
        (0,) * level,
    )
    D = _delay(level, wavelet)
    y = synthesize_block(dec, n_samples=n + D)
    np.testing.assert_allclose(y[D : D + n], ref[:n], rtol=0, atol=1e-12)


@pytest.mark.parametrize("wavelet", ["haar", "db2", "sym4", "coif1", "db8"])
@pytest.mark.parametrize("level", [1, 2, 5])
@pytest.mark.parametrize("kind", ["detail", "approximation"])
def test_basis_function_is_pywt_upcoef(wavelet: str, level: int, kind: str) -> None:
    ref = pywt.upcoef("d" if kind == "detail" else "a", [1.0], wavelet, level=level)
    got = basis_function(wavelet, level, kind)
    assert got.size == (2**level - 1) * (pywt.Wavelet(wavelet).dec_len - 1) + 1
    np.testing.assert_allclose(got, ref[: got.size], rtol=0, atol=1e-13)
    np.testing.assert_allclose(ref[got.size :], 0.0, atol=1e-13)
    assert np.linalg.norm(got) == pytest.approx(1.0, abs=1e-10)


def test_haar_basis_is_eq_4_4() -> None:
    s = 1 / np.sqrt(2)
    # psi_{2k+1}[n]: +1/sqrt(2) at n = 2k, -1/sqrt(2) at n = 2k + 1; psi_{2k}: both +
    np.testing.assert_allclose(basis_function("haar", 1), [s, -s], atol=1e-15)
    np.testing.assert_allclose(basis_function("haar", 1, "approximation"), [s, s], atol=1e-15)
    # eq. 4.3 dilated to 8 samples, unit energy
    np.testing.assert_allclose(
        basis_function("haar", 3), np.repeat([1.0, -1.0], 4) / np.sqrt(8), atol=1e-15
    )


def test_late_coefficient_is_refused() -> None:
    syn = SynthesisFilterbank("haar", 2, 1)
    for _ in range(10):
        syn.step()
    with pytest.raises(ValueError, match="already returned"):
        syn.add(1, "detail", 0, [1.0])
    with pytest.raises(ValueError, match="level"):
        syn.add(3, "detail", 9, [1.0])
    with pytest.raises(ValueError, match="approximation of level 2"):
        syn.add(1, "approximation", 9, [1.0])


def test_future_coefficient_places_basis(rng: np.random.Generator) -> None:
    """A coefficient added far ahead lands on its documented output samples."""
    syn = SynthesisFilterbank("db2", 3, 1)
    D = syn.delay
    m = 40
    syn.add(2, "detail", m, [2.0])
    y = np.array([syn.step()[0] for _ in range(4 * m + 4 * 4 + D + 10)])
    g = basis_function("db2", 2)
    start = 4 * (m + 1) + D - g.size
    np.testing.assert_allclose(y[start : start + g.size], 2.0 * g, atol=1e-15)
    y[start : start + g.size] = 0.0
    np.testing.assert_array_equal(y, 0.0)


def _streamed_atom(wavelet: str, level: int, kind: str) -> np.ndarray:
    """Weights of one coefficient's support samples, from impulses through the analysis bank."""
    S = (2**level - 1) * (pywt.Wavelet(wavelet).dec_len - 1) + 1
    end = 2**level * (S // 2**level + 2) - 1  # a coefficient of `level` completes here
    weights = np.zeros(S)
    for t in range(S):
        bank = AnalysisFilterbank(wavelet, level, 1)
        x = np.zeros(end + 1)
        x[end - S + 1 + t] = 1.0
        for n, v in enumerate(x):
            for c in bank.step([v], n):
                if c.level == level and c.kind == kind and c.last_sample_index == end:
                    assert c.first_sample_index == end - S + 1
                    weights[t] = c.values[0]
    return weights


@pytest.mark.parametrize("wavelet", ["haar", "db2", "db4", "sym4", "coif1"])
@pytest.mark.parametrize("level", [1, 2, 3])
@pytest.mark.parametrize("kind", ["detail", "approximation"])
def test_atom_time_centre_of_the_streamed_coefficient(wavelet: str, level: int, kind: str) -> None:
    # reference: the energy centroid of the weights the streaming analysis gives each sample
    # of the support (impulse responses), and of pywt.upcoef's atom
    w = _streamed_atom(wavelet, level, kind)
    assert np.linalg.norm(w) == pytest.approx(1.0, abs=1e-9)
    t = np.arange(w.size)
    ref = float(t @ w**2)
    assert atom_time_centre(wavelet, level, kind) == pytest.approx(ref, abs=1e-9)
    up = pywt.upcoef("d" if kind == "detail" else "a", [1.0], wavelet, level=level)[: w.size]
    assert atom_time_centre(wavelet, level, kind) == pytest.approx(float(t @ up**2), abs=1e-9)


def test_daubechies_atoms_lean_to_the_recent_samples() -> None:
    # extremal phase: energy on the latest samples of the support; haar symmetric
    assert atom_time_centre("haar", 1) == pytest.approx(0.5)
    assert atom_time_centre("haar", 3) == pytest.approx(3.5)
    for wavelet, S in (("db2", 4), ("db4", 8)):
        assert atom_time_centre(wavelet, 1) > (S - 1) / 2
