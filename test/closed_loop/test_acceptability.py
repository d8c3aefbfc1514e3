"""
Figure 8.4 machinery: run classification, envelope growth, nominal linear-rate limit.

References come from outside the code under test: geometric sequences with a known ratio,
and the closed-loop poles of the nominal delayed loop written out by hand from eq. 8.11
(``1 + alpha (z - 1)(z^i - 1) = 0``) and solved with numpy.roots.
"""

import math

import numpy as np
import pytest

from amb_apps.acceptability import (
    ACCEPTABLE,
    UNSTABLE,
    SweepSetup,
    envelope_growth,
    grid_values,
    nominal_linear_rate_limit,
)


def _oscillation(ratio, n=40, omega=0.7):
    k = np.arange(n)
    return (ratio**k * np.exp(1j * omega * k))[:, None] * np.ones((1, 8)) * 1e-4


@pytest.mark.parametrize("ratio", [0.8, 0.95, 1.03, 1.1])
def test_envelope_growth_recovers_the_ratio_of_a_geometric_oscillation(ratio):
    growth, converged = envelope_growth(_oscillation(ratio))
    if ratio < 0.85:
        assert converged  # 0.8^30 is far below the 2 % noise fraction
    else:
        assert not converged
        assert growth == pytest.approx(ratio, rel=2e-3)


def test_a_prescribed_linear_ramp_is_not_taken_for_growth():
    k = np.arange(40)
    # fault step at k = 2, then the remaining fraction falls by 0.02 per period
    frac = np.where(k < 2, 0.0, np.clip(1 - 0.02 * (k - 2), 0, None))
    ramp = frac[:, None] * np.ones((1, 8)) * (1 + 1j) * 1e-4
    growth, converged = envelope_growth(ramp)
    assert converged and growth == 0.0


def _nominal_linear_stable(rate: float, delay: int) -> bool:
    c = np.clip(1 - rate * np.arange(1, math.ceil(1 / rate) + 1), 0, None)
    c = np.trim_zeros(c, "b")
    # alpha(z) = sum c_k z^-k; multiply 1 + alpha (z-1)(z^i-1) by z^K (K = len(c)):
    big_k = c.size
    poly = np.zeros(big_k + delay + 2)
    poly[delay + 1] += 1.0  # z^K as descending coefficients of degree K + i + 1
    a = np.zeros(big_k + 1)
    a[1:] = c  # z^K alpha = sum c_k z^(K-k), descending: index k
    prod = np.polymul(np.polymul(a, [1, -1]), np.concatenate(([1.0], np.zeros(delay - 1), [-1.0])))
    poly = np.polyadd(poly, prod)
    return bool(np.max(np.abs(np.roots(np.trim_zeros(poly, "f")))) < 1)


@pytest.mark.parametrize("delay", [1, 2, 3])
def test_nominal_linear_rate_limit_matches_hand_written_characteristic_polynomial(delay):
    limit = nominal_linear_rate_limit(delay, step=0.01)
    rates = np.arange(0.01, limit + 1e-9, 0.01)
    assert all(_nominal_linear_stable(r, delay) for r in rates)
    assert not _nominal_linear_stable(limit + 0.01, delay)


@pytest.mark.slow
def test_thesis_linear_rate_lies_at_the_nominal_delay_2_limit():
    # thesis 8.5.1: 0.31 per step at delay 2; the nominal loop allows up to 0.294
    assert nominal_linear_rate_limit(2) == pytest.approx(0.31, abs=0.02)


def test_grid_contains_the_section_853_settings():
    g = grid_values(10)
    assert np.any(np.isclose(g, 0.75)) and np.any(np.isclose(g, 0.65))
    with pytest.raises(ValueError, match="grid must be an integer >= 2"):
        grid_values(1)


@pytest.fixture(scope="module")
def setup():
    return SweepSetup.first_critical()


def test_thesis_design_point_is_acceptable_and_a_small_gain_runs_away(setup):
    good = setup.run(w=0.75, v=0.75)
    assert good.label == ACCEPTABLE
    assert good.peak_radius < 0.5e-3 and good.steady_1x < 0.1 * 141e-6
    bad = setup.run(w=0.15, v=0.15)  # far outside the nominal boundary of figure 8.3
    assert bad.label == UNSTABLE and bad.guard_tripped
    assert bad.peak_radius > 0.5e-3


@pytest.mark.slow
def test_coarse_map_follows_the_nominal_boundary_where_it_is_clear(setup):
    from amb_apps.acceptability import exponential_sweep

    w = v = np.array([0.15, 0.75])
    out = exponential_sweep(setup, w, v, jobs=2)  # the parallel path, as amb-acceptability
    # (w, v) = (0.15, *) nominally unstable, (0.75, 0.75) nominally stable
    assert out["label"][0][0] == UNSTABLE and out["label"][1][0] == UNSTABLE
    assert out["label"][1][1] == ACCEPTABLE
    assert out["nominal_stable"] == [[False, False], [False, True]]
