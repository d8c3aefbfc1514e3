"""Robust thresholds: median + k * 1.4826 * MAD against scipy.stats, floor, errors."""

import numpy as np
import pytest
from scipy import stats

from amb_fault_monitor.calibration import median, robust_threshold
from amb_fault_monitor.errors import FaultMonitorError


def test_threshold_equals_scipy_median_and_mad():
    rng = np.random.default_rng(1)
    x = np.abs(rng.standard_normal((5000, 4))) * np.array([1.0, 2.0, 3.0, 4.0])
    ref = np.median(x, axis=0) + 8.0 * stats.median_abs_deviation(x, axis=0, scale="normal")
    np.testing.assert_allclose(robust_threshold(x, 8.0, 0.0), ref, rtol=2e-4)


def test_rayleigh_false_crossing_rate_matches_closed_form():
    # plane features are hypot of two Gaussians (Rayleigh, scale s): P(r > c) = exp(-c^2 / 2 s^2)
    rng = np.random.default_rng(2)
    r = np.hypot(rng.standard_normal(400_000), rng.standard_normal(400_000))
    thr = float(robust_threshold(r, 2.0, 0.0))
    expected = np.exp(-(thr**2) / 2)
    assert np.mean(r > thr) == pytest.approx(expected, rel=0.1)
    # k = 8 (the default) puts it far beyond: exp(-6.5^2 / 2) < 1e-9
    assert np.exp(-(float(robust_threshold(r, 8.0, 0.0)) ** 2) / 2) < 1e-8


def test_outliers_in_window_do_not_inflate_threshold():
    rng = np.random.default_rng(3)
    x = np.abs(rng.standard_normal(1000))
    clean = robust_threshold(x, 8.0, 0.0)
    x[:50] = 1e3  # a 5 % disturbance inside the calibration window
    assert robust_threshold(x, 8.0, 0.0) < 1.2 * clean


def test_floor_applies_to_noise_free_features():
    assert robust_threshold(np.zeros(20), 8.0, 2e-8) == pytest.approx(2e-8)


@pytest.mark.parametrize(
    ("x", "k", "floor", "match"),
    [(np.ones(3), 8.0, 0.0, "lengthen the calibration"), (np.ones(20), 0.0, 0.0, "k must be"),
     (np.ones(20), 1.0, -1.0, "floor")],
)  # fmt: skip
def test_errors(x, k, floor, match):
    with pytest.raises(FaultMonitorError, match=match):
        robust_threshold(x, k, floor)


@pytest.mark.parametrize("shape", [(1,), (8,), (9,), (16, 4), (17, 4), (3, 2, 5)])
def test_median_equals_numpys(shape) -> None:
    """The sort-based median averages the same two middle values as ``numpy.median``."""
    x = np.random.default_rng(sum(shape)).normal(size=shape) * 1e-6
    assert median(x) == np.median(x)
    np.testing.assert_array_equal(median(x, axis=0), np.median(x, axis=0))
    with pytest.raises(ValueError, match="empty"):
        median(np.zeros((0, 4)), axis=0)
