"""Prescribed responses alpha(z) (thesis eq. 8.6-8.7) against hand-derived closed forms."""

import numpy as np
import pytest

from amb_controller.errors import ControllerValueError
from amb_controller.response import PrescribedResponse


@pytest.mark.parametrize(("w", "v"), [(0.75, 0.75), (0.3, 0.9), (0.9, 0.0)])
def test_exponential_series_is_w_v_power(w, v):
    # eq. 8.6: w/(z - v) = w z^-1 / (1 - v z^-1) = sum_k w v^(k-1) z^-k
    c = PrescribedResponse.exponential(w, v).series(12)
    np.testing.assert_allclose(c, w * v ** np.arange(12), rtol=1e-13, atol=1e-15)


def test_linear_decay_series():
    c = PrescribedResponse.linear_decay(0.2).series(8)
    np.testing.assert_allclose(c, [0.8, 0.6, 0.4, 0.2, 0.0, 0.0, 0.0, 0.0], atol=1e-14)


def test_from_series_round_trip():
    c = [0.5, 0.25, 0.1]
    np.testing.assert_allclose(PrescribedResponse.from_series(c).series(5), [0.5, 0.25, 0.1, 0, 0])


def test_beta_matches_direct_formula_on_z_plane():
    # beta(z) = 1/(alpha(z)(z-1)) - 1 with alpha = w/(z-v), evaluated directly.
    w, v = 0.6, 0.8
    num, den = PrescribedResponse.exponential(w, v).beta()
    rng = np.random.default_rng(1)
    z = rng.normal(size=7) + 1j * rng.normal(size=7)
    x = 1 / z
    beta = np.polyval(num[::-1], x) / np.polyval(den[::-1], x)
    direct = (z - v) / (w * (z - 1)) - 1
    np.testing.assert_allclose(beta, direct, rtol=1e-12)
    # hand form: ((1-w) + (w-v) z^-1) / (w (1 - z^-1)), normalised by w
    np.testing.assert_allclose(num, [(1 - w) / w, (w - v) / w], rtol=1e-13)
    np.testing.assert_allclose(den, [1.0, -1.0])


def test_linear_decay_controller_poles_inside_unit_circle():
    # Enestrom-Kakeya: decreasing positive c_k put the zeros of alpha inside |z| <= 1.
    for rate in (0.1, 0.2, 0.31):
        poles = PrescribedResponse.linear_decay(rate).controller_poles()
        assert np.all(np.abs(poles) < 1.0)


@pytest.mark.parametrize(
    ("w", "v"), [(0.0, 0.5), (-0.1, 0.5), (0.5, 1.0), (0.5, -0.1), (np.nan, 0.5)]
)
def test_exponential_rejects_out_of_range(w, v):
    with pytest.raises(ValueError, match=r"needs (w > 0|0 <= v < 1)"):
        PrescribedResponse.exponential(w, v)


def test_series_with_zero_first_term_is_refused():
    with pytest.raises(ControllerValueError, match="c_1"):
        PrescribedResponse.from_series([0.0, 0.5])
