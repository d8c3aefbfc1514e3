"""
Stability criterion of eq. 8.15-8.16 and the (w, v) maps of figure 8.3.

References: the Jury conditions for quadratics and cubics (derived by hand below),
numpy.roots of the hand-expanded characteristic polynomial, and the thesis's own
statements about section 8.5 (operating points and the linear-decay limit).
"""

import itertools

import numpy as np
import pytest

from amb_controller.response import PrescribedResponse
from amb_controller.stability import (
    characteristic_polynomial,
    exponential_stability_map,
    gamma,
    is_nominally_stable,
    nominal_poles,
    robustness_norm,
)

W = np.linspace(0.01, 0.99, 99)
V = np.linspace(0.0, 0.99, 100)


@pytest.mark.parametrize("delay", [1, 2, 3, 4])
def test_characteristic_polynomial_hand_expansion(delay):
    # (z - v) + w (z - 1)(z^i - 1) = w z^(i+1) - w z^i + (1 - w) z + (w - v)
    w, v = 0.7, 0.4
    p = characteristic_polynomial(PrescribedResponse.exponential(w, v), delay)
    expected = np.zeros(delay + 2)
    expected[0] += w
    expected[1] -= w
    expected[delay] += 1 - w
    expected[delay + 1] += w - v
    np.testing.assert_allclose(p, expected, atol=1e-15)
    np.testing.assert_allclose(
        np.sort_complex(nominal_poles(PrescribedResponse.exponential(w, v), delay)),
        np.sort_complex(np.roots(expected)),
        atol=1e-12,
    )


def test_gamma_denominator_vanishes_at_nominal_poles():
    alpha = PrescribedResponse.exponential(0.65, 0.65)
    poles = nominal_poles(alpha, 2)
    w, v = 0.65, 0.65
    # direct eq. 8.15 with alpha = w/(z - v)
    z = np.array([0.3 + 0.2j, -0.5j, 1.5])
    a = w / (z - v)
    np.testing.assert_allclose(
        gamma(alpha, 2, z), (1 - a * (z - 1)) / (1 + a * (z - 1) * (z**2 - 1)), rtol=1e-12
    )
    assert np.all(np.abs(1 / gamma(alpha, 2, poles)) < 1e-9)


def _away_from(values, boundary, tol=2e-3):
    return np.abs(values - boundary) > tol


def test_delay_one_map_equals_jury_region():
    # i = 1: w z^2 + (1 - 2w) z + (w - v). Jury for a z^2 + b z + c with a > 0:
    # |c| < a  <=>  0 < v < 2w ;  P(1) = 1 - v > 0 ;  P(-1) = 4w - 1 - v > 0.
    m = exponential_stability_map(W, V, 1)
    ww, vv = np.meshgrid(W, V)
    jury = (vv > 0) & (vv < 2 * ww) & (vv < 4 * ww - 1)
    clear = _away_from(vv, 0) & _away_from(vv, 2 * ww) & _away_from(vv, 4 * ww - 1)
    assert clear.sum() > 8000
    np.testing.assert_array_equal(m[clear], jury[clear])


def test_delay_two_map_equals_jury_region():
    # i = 2: w z^3 - w z^2 + (1 - w) z + (w - v) = a3 z^3 + a2 z^2 + a1 z + a0.
    # Jury (cubic, a3 > 0): P(1) > 0, -P(-1) > 0, |a0| < a3, |a0^2 - a3^2| > |a0 a2 - a1 a3|.
    m = exponential_stability_map(W, V, 2)
    ww, vv = np.meshgrid(W, V)
    a3, a2, a1, a0 = ww, -ww, 1 - ww, ww - vv
    p1 = a3 + a2 + a1 + a0  # = 1 - v
    pm1 = -a3 + a2 - a1 + a0  # = -(1 + v): always satisfied
    c3 = np.abs(a0) - a3
    c4 = np.abs(a0**2 - a3**2) - np.abs(a0 * a2 - a1 * a3)
    jury = (p1 > 0) & (-pm1 > 0) & (c3 < 0) & (c4 > 0)
    clear = (np.abs(c3) > 2e-3) & (np.abs(c4) > 2e-3) & (np.abs(pm1) > 2e-3)
    assert clear.sum() > 8000
    np.testing.assert_array_equal(m[clear], jury[clear])


def test_regions_shrink_with_delay_as_figure_8_3():
    # Thesis section 8.4 on figure 8.3: "the effect of system delays is evident showing
    # controller performance to be limited by longer evaluation times". We compare the
    # region areas (strictly decreasing with i = 1..4) and nesting (each region inside
    # the one for the shorter delay, up to grid points on the boundary).
    maps = [exponential_stability_map(W, V, i) for i in (1, 2, 3, 4)]
    areas = [m.mean() for m in maps]
    assert areas[0] > areas[1] > areas[2] > areas[3] > 0.05
    for shorter, longer in itertools.pairwise(maps):
        assert np.sum(longer & ~shorter) <= 0.002 * longer.size


def test_delay_two_region_contains_thesis_operating_points():
    # Section 8.5: with a 2-cycle delay the rig ran w = v = 0.75 (figs 8.5-8.14), 0.65
    # (fig 8.15, "flutter due to over compensation") and 0.9 (fig 8.16, slow decay).
    for wv in (0.65, 0.75, 0.9):
        assert is_nominally_stable(PrescribedResponse.exponential(wv, wv), 2)
    fast = nominal_poles(PrescribedResponse.exponential(0.65, 0.65), 2)
    slow = nominal_poles(PrescribedResponse.exponential(0.9, 0.9), 2)
    # flutter: an oscillatory pair for 0.65; no oscillation and a slow pole for 0.9
    assert np.max(np.abs(fast.imag)) > 0.4
    assert np.allclose(slow.imag, 0.0) and np.max(np.abs(slow)) > 0.85
    # strong gains (small w) are unstable with delay 2: region bounded away from w = 0
    assert not exponential_stability_map(W, V, 2)[:, W < 0.45].any()


def test_linear_decay_limit_near_thesis_value_for_two_period_delay():
    # Section 8.5.1: the experimental limit on the linear decay rate at 11 Hz with the
    # 2-cycle delay was 0.31 per step. The nominal stability limit of c_k = 1 - r k must
    # lie close to it (acceptability on the rig is not nominal stability; 10 % band).
    rates = np.arange(0.20, 0.40, 0.001)
    stable = np.array([is_nominally_stable(PrescribedResponse.linear_decay(r), 2) for r in rates])
    limit = rates[np.argmin(stable)]
    assert stable[rates < limit].all()
    assert abs(limit - 0.31) < 0.031


def test_robustness_norm_scalar_perfect_inverse_is_max_gamma():
    # (G B_u)^* = 1/g constant: ||B gamma||_inf = max |gamma| / g, checked on a dense grid.
    g = 2.0
    alpha = PrescribedResponse.exponential(0.75, 0.75)
    inv = np.full((1, 1, 1), 1 / g)
    z = np.exp(1j * np.linspace(0, np.pi, 20001))
    a = 0.75 / (z - 0.75)
    direct = np.max(np.abs((1 - a * (z - 1)) / (1 + a * (z - 1) * (z**2 - 1)))) / g
    assert robustness_norm(inv, alpha, 2, n_points=20001) == pytest.approx(direct, rel=1e-9)
    unstable = PrescribedResponse.exponential(0.2, 0.5)
    assert robustness_norm(inv, unstable, 2) == np.inf
