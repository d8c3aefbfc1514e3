"""Filters from PyWavelets' tables and the errors for names that are not allowed."""

from __future__ import annotations

import decimal

import numpy as np
import pytest
import pywt

from amb_wavelet.errors import WaveletNameError
from amb_wavelet.filters import get_filters, orthogonal_wavelet_names


def test_names_cover_the_issue_list() -> None:
    names = set(orthogonal_wavelet_names())
    expected = (
        {"haar", "dmey"}
        | {f"db{i}" for i in range(1, 21)}
        | {f"sym{i}" for i in range(2, 21)}
        | {f"coif{i}" for i in range(1, 18)}
    )
    assert expected <= names
    assert not any(n.startswith(("bior", "rbio")) for n in names)


@pytest.mark.parametrize("name", ["haar", "db1", "db7", "db20", "sym11", "coif17", "dmey"])
def test_filters_are_pywavelets_tables(name: str) -> None:
    f = get_filters(name)
    w = pywt.Wavelet(name)
    np.testing.assert_array_equal(f.dec_lo, w.dec_lo)
    np.testing.assert_array_equal(f.dec_hi, w.dec_hi)
    np.testing.assert_array_equal(f.rec_lo, w.rec_lo)
    np.testing.assert_array_equal(f.rec_hi, w.rec_hi)
    assert f.length == w.dec_len
    # synthesis filters are the time reverses of the analysis filters (g[n] = h[-n])
    np.testing.assert_array_equal(f.rec_lo, f.dec_lo[::-1])


def test_haar_is_eq_4_7() -> None:
    f = get_filters("haar")
    s = 1 / np.sqrt(2)
    np.testing.assert_allclose(f.dec_lo, [s, s], rtol=0, atol=1e-15)
    np.testing.assert_allclose(sorted(f.dec_hi), [-s, s], rtol=0, atol=1e-15)
    assert f.orthonormality_error < 1e-15


@pytest.mark.parametrize(
    ("name", "bound"),
    [("haar", 3e-16), ("db2", 3e-16), ("db4", 3e-16), ("sym4", 1e-11), ("dmey", 1e-2)],
)
def test_orthonormality_error_reported(name: str, bound: float) -> None:
    """The error of PyWavelets' table, summed exactly in 60-digit decimal arithmetic.

    Decimal(float) is exact and a product of two doubles needs 106 bits (32 digits), so the
    reference has no rounding error of its own; for db4 the value (~6e-17) is below one ulp
    of 1, which any double-precision sum would replace by its own rounding noise.
    """
    with decimal.localcontext(decimal.Context(prec=60)):
        h = [decimal.Decimal(t) for t in pywt.Wavelet(name).dec_lo]
        lags = [sum(h[n] * h[n + 2 * k] for n in range(len(h) - 2 * k)) for k in range(len(h) // 2)]
        expected = float(max([abs(lags[0] - 1), *(abs(v) for v in lags[1:])]))
    assert expected > 0.0  # the tables are not exactly orthonormal: the check has a value to check
    assert get_filters(name).orthonormality_error == pytest.approx(expected, rel=1e-12)
    assert expected < bound


def test_case_insensitive() -> None:
    assert get_filters("DB2").wavelet == "db2"


@pytest.mark.parametrize(
    ("name", "words"),
    [
        ("bior2.2", "biorthogonal"),
        ("rbio1.3", "biorthogonal"),
        ("morl", "continuous"),
        ("db99", "unknown"),
        ("wavelet", "unknown"),
    ],
)
def test_bad_names_raise_clear_errors(name: str, words: str) -> None:
    with pytest.raises(WaveletNameError, match=words) as info:
        get_filters(name)
    assert "orthogonal_wavelet_names" in str(info.value)
    assert isinstance(info.value, ValueError)


def test_non_string_name() -> None:
    with pytest.raises(WaveletNameError, match="str"):
        get_filters(4)  # type: ignore[arg-type]
