"""Truncated pseudo-inverse series (eq. 6.35) against closed-form inverses."""

import numpy as np
import pytest

from amb_controller.errors import ControllerValueError
from amb_controller.inverse import dc_gain, pseudo_inverse_series, series_product


def test_scalar_first_order_inverse_is_exact_fir():
    # G = g / (1 - a z^-1) (Markov g a^k); its inverse (1 - a z^-1)/g is FIR of order 1.
    g, a = 2.0, 0.6
    markov = (g * a ** np.arange(40)).reshape(-1, 1, 1)
    inv = pseudo_inverse_series(markov, order=3)
    np.testing.assert_allclose(inv[:, 0, 0], [1 / g, -a / g, 0, 0], atol=1e-10)


def test_fir_plant_inverse_matches_power_series_division():
    # G = 1 + 0.5 z^-1: inverse 1/(1 + 0.5 z^-1) = sum (-0.5)^k z^-k; truncation at 10
    # leaves a residual (0.5)^11 in the product, so the LS solution is close to the series.
    markov = np.array([1.0, 0.5]).reshape(2, 1, 1)
    inv = pseudo_inverse_series(markov, order=10)
    np.testing.assert_allclose(inv[:, 0, 0], (-0.5) ** np.arange(11), atol=2e-3)


def test_tall_static_plant_gives_moore_penrose_left_inverse():
    rng = np.random.default_rng(0)
    g = rng.normal(size=(8, 4))
    inv = pseudo_inverse_series(g[None], order=2)
    np.testing.assert_allclose(inv[0], np.linalg.pinv(g), atol=1e-12)
    np.testing.assert_allclose(inv[1:], 0.0, atol=1e-12)


def test_left_inverse_product_is_identity_for_invertible_mimo_fir():
    # Square MIMO G = A0 + A1 z^-1 with det(A0) != 0 and small A1: B * A ~ delta I.
    rng = np.random.default_rng(3)
    a0 = np.eye(3) + 0.1 * rng.normal(size=(3, 3))
    a1 = 0.2 * rng.normal(size=(3, 3))
    inv = pseudo_inverse_series(np.stack([a0, a1]), order=10)
    prod = series_product(inv, np.stack([a0, a1]))
    np.testing.assert_allclose(prod[0], np.eye(3), atol=1e-4)
    assert np.max(np.abs(prod[1:])) < 1e-3


def test_lead_targets_delayed_identity():
    # G = z^-1 g: no causal inverse at k = 0, but B = z^0/g gives B G = z^-1.
    markov = np.array([0.0, 3.0]).reshape(2, 1, 1)
    inv = pseudo_inverse_series(markov, order=2, lead=1)
    np.testing.assert_allclose(inv[:, 0, 0], [1 / 3, 0, 0], atol=1e-12)


def test_regularisation_shrinks_gain():
    markov = np.array([0.01, 1.0]).reshape(2, 1, 1)
    plain = pseudo_inverse_series(markov, order=5)
    ridge = pseudo_inverse_series(markov, order=5, regularisation=0.3)
    assert np.abs(ridge).sum() < np.abs(plain).sum()


def test_dc_gain():
    np.testing.assert_allclose(dc_gain(np.ones((4, 2, 3))), 4 * np.ones((2, 3)))


def test_invalid_order_is_refused():
    with pytest.raises(ControllerValueError, match="order"):
        pseudo_inverse_series(np.ones((2, 1, 1)), order=-1)


def _rank_two_static(noise: float) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(5)
    u, _ = np.linalg.qr(rng.normal(size=(8, 8)))
    v, _ = np.linalg.qr(rng.normal(size=(4, 4)))
    s = np.zeros((8, 4))
    s[0, 0], s[1, 1] = 3e-7, 1e-7  # m/N-like magnitudes; directions 3, 4 null
    exact = u @ s @ v.T
    return exact, exact + noise * rng.normal(size=exact.shape)


def test_rank_rtol_gives_the_moore_penrose_inverse_of_a_rank_deficient_static_gain():
    exact, noisy = _rank_two_static(3e-20)  # 1e-13 relative in the null directions
    inv = pseudo_inverse_series(noisy[None], order=1, dc_weight=10.0, rank_rtol=1e-8)
    np.testing.assert_allclose(inv[0] + inv[1], np.linalg.pinv(exact, rcond=1e-8), rtol=1e-6)
    # B(1) G(1) is the projector onto the row space (Penrose G B G = G), not I
    np.testing.assert_allclose(exact @ (inv[0] + inv[1]) @ exact, exact, atol=1e-12 * 3e-7)
    plain = pseudo_inverse_series(noisy[None], order=1, dc_weight=10.0)
    assert np.abs(plain).max() > 1e3 * np.abs(np.linalg.pinv(exact, rcond=1e-8)).max()


def test_rank_rtol_inverse_of_rank_deficient_first_order_plant_is_exact_fir():
    # A^(k) = a^k M with rank(M) = 2: G = M / (1 - a z^-1), inverse (1 - a z^-1) M^+.
    a = 0.6
    m, _ = _rank_two_static(0.0)
    markov = a ** np.arange(40)[:, None, None] * m[None]
    inv = pseudo_inverse_series(markov, order=3, rank_rtol=1e-8)
    pinv = np.linalg.pinv(m, rcond=1e-8)
    np.testing.assert_allclose(inv[0], pinv, rtol=1e-8, atol=1e-8 * np.abs(pinv).max())
    np.testing.assert_allclose(inv[1], -a * pinv, rtol=1e-8, atol=1e-8 * np.abs(pinv).max())
    np.testing.assert_allclose(inv[2:], 0.0, atol=1e-8 * np.abs(pinv).max())


@pytest.mark.parametrize("wavelet", ["haar", "db2", "db4"])
def test_two_quadrature_control_waveforms_are_dependent_at_levels_two_and_three(wavelet):
    # Odd waveform = even advanced by N/4. Level 2 (two half-period wavelets): the sum of
    # the four waveforms of one axis vanishes (by hand for haar: +-16-sample blocks), rank 3.
    # Level 3 (quarter-period wavelets): odd q repeats even q + 2, rank 4 of 8.
    from amb_controller.basis import control_basis

    n = 64
    for p, rank in ((1, 2), (2, 3), (3, 4)):
        basis = control_basis(wavelet, n, [p], n_axes=1)
        assert np.linalg.matrix_rank(basis.weights[:, 0, :], tol=1e-9) == rank


def test_rank_rtol_out_of_range_is_refused():
    with pytest.raises(ControllerValueError):
        pseudo_inverse_series(np.ones((2, 1, 1)), order=1, rank_rtol=1.0)
    with pytest.raises(ControllerValueError):
        pseudo_inverse_series(np.zeros((2, 2, 2)), order=1, rank_rtol=1e-8)
