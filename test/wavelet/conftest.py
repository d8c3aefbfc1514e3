"""Shared fixtures for the wavelet core tests."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import pywt


def _pywt_wavedec(x: np.ndarray, wavelet: str, level: int) -> list[np.ndarray]:
    """``pywt.wavedec`` in zero mode along axis 0, without its too-deep-level warning."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return pywt.wavedec(x, wavelet, mode="zero", level=level, axis=0)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20060601)


def _make_signals(rng: np.random.Generator, n: int = 300, channels: int = 3) -> dict:
    """A random signal and a sum of sinusoids (synchronous + 3x + off-grid tone)."""
    t = np.arange(n)[:, None]
    phase = rng.uniform(0, 2 * np.pi, channels)
    sine = (
        1e-4 * np.sin(2 * np.pi * t / 32 + phase)
        + 3e-5 * np.cos(2 * np.pi * 3 * t / 32 - phase)
        + 1e-5 * np.sin(0.377 * t)
    )
    return {"random": rng.standard_normal((n, channels)), "sinusoid": sine}


@pytest.fixture
def make_signals():
    """Factory ``make_signals(rng, n, channels) -> {"random": ..., "sinusoid": ...}``."""
    return _make_signals


@pytest.fixture
def wavedec_zero():
    """Factory ``wavedec_zero(x, wavelet, level)``: PyWavelets' reference transform."""
    return _pywt_wavedec
