"""Steady-state prediction (eq. 7.2-7.6) and proportional / moderated control (eq. 7.7-7.9)."""

import numpy as np
import pytest

from amb_controller.inverse import pseudo_inverse_series
from amb_controller.lti import DiscreteStateSpace
from amb_controller.stability import closed_loop
from amb_controller.steady_state import (
    ProportionalController,
    SteadyStatePredictor,
    collocated_gain,
    steady_state_operator,
)


def _first_order_markov(g, a, n=60):
    return (g * a ** np.arange(n)).reshape(-1, 1, 1)


def _first_order_plant(g, a):
    """g / (1 - a z^-1) as state space: Markov g, g a, g a^2, ..."""
    return DiscreteStateSpace([[a]], [[1.0]], [[g * a]], [[g]])


def test_prediction_reaches_final_value_in_the_first_period():
    # G = g / (1 - a z^-1); step F = 1 from k = 0: Q[k] = g (1 - a^(k+1)) / (1 - a) and the
    # final value (eq. 7.5) is g / (1 - a). The exact inverse (order 1) predicts it at once.
    g, a = 0.8, 0.85
    markov = _first_order_markov(g, a, 200)
    inv = pseudo_inverse_series(markov, order=1)
    pred = SteadyStatePredictor(steady_state_operator(markov, inv))
    k = np.arange(30)
    q = g * (1 - a ** (k + 1)) / (1 - a)
    w = np.array([pred.step(i, np.array([q[i]]))[0] for i in k])
    np.testing.assert_allclose(w, g / (1 - a), rtol=1e-9)
    assert abs(q[0] - g / (1 - a)) > 0.8 * g / (1 - a)  # the measurement is far from it


def test_prediction_mimo_oscillatory_plant_is_exact_with_exact_order():
    # G = (I - F z^-1)^-1 M with F oscillatory (eigenvalues 0.8 e^{+-0.6j}): Markov F^k M,
    # exact inverse M^-1 (I - F z^-1) of order 1; final value (I - F)^-1 M step. The
    # order-5 least-squares inverse (thesis's truncation) must find it too.
    rng = np.random.default_rng(2)
    rot = 0.8 * np.array([[np.cos(0.6), -np.sin(0.6)], [np.sin(0.6), np.cos(0.6)]])
    basis = rng.normal(size=(2, 2))
    f = basis @ rot @ np.linalg.inv(basis)
    m = rng.normal(size=(2, 2))
    markov = np.stack([np.linalg.matrix_power(f, k) @ m for k in range(150)])
    inv = pseudo_inverse_series(markov, order=5)
    np.testing.assert_allclose(inv[0], np.linalg.inv(m), atol=1e-8)
    np.testing.assert_allclose(inv[1], -np.linalg.inv(m) @ f, atol=1e-8)
    pred = SteadyStatePredictor(steady_state_operator(markov, inv))
    step = np.array([1.0, -2.0])
    q = np.cumsum(markov, axis=0) @ step  # measured step response (overshooting)
    final = np.linalg.solve(np.eye(2) - f, m @ step)
    w = np.array([pred.step(i, q[i]) for i in range(20)])
    np.testing.assert_allclose(w, np.tile(final, (20, 1)), atol=1e-7 * np.abs(final).max())
    assert np.abs(q[:5] - final).max() > 0.3 * np.abs(final).max()


def test_dc_weight_restores_steady_state_gain_of_truncated_inverse():
    # Slow plant, short inverse: plain LS misses B(1) G(1) = I, the DC equations fix it.
    markov = (0.5 * 0.95 ** np.arange(300)).reshape(-1, 1, 1)
    markov[0] += 0.2
    gdc = markov.sum()
    for weight, tol in ((0.0, None), (100.0, 1e-3)):
        inv = pseudo_inverse_series(markov, order=3, dc_weight=weight)
        err = abs(inv.sum() * gdc - 1.0)
        if tol is None:
            assert err > 1e-2
        else:
            assert err < tol


@pytest.mark.parametrize("delay", [1, 3])
def test_proportional_and_moderated_loop_poles_match_hand_polynomials(delay):
    # Plant g / (1 - a x), x = z^-1. Proportional: 1 + k x^i G = 0
    #   -> z^i - a z^(i-1) + k g = 0.
    # Moderated with exact S = Gamma (1 - a x)/g: G S = Gamma, so 1 + k Gamma x^i = 0
    #   -> z^i = -k Gamma.
    g, a, k = 0.5, 0.9, 0.1  # k Gamma = 0.5: moderated loop stable
    markov = _first_order_markov(g, a, 300)
    plant = _first_order_plant(g, a)
    prop = ProportionalController(np.array([[k]]), delay)
    poles = closed_loop(plant, prop.state_space()).poles()
    char = np.zeros(delay + 1)
    char[0], char[1] = 1.0, -a
    char[delay] += k * g
    expected = np.roots(char)
    poles = poles[np.abs(poles) > 1e-9]  # the delay line adds poles at z = 0
    np.testing.assert_allclose(np.sort_complex(poles), np.sort_complex(expected), atol=1e-9)
    inv = pseudo_inverse_series(markov, order=1)
    mod = ProportionalController(
        np.array([[k]]), delay, SteadyStatePredictor(steady_state_operator(markov, inv))
    )
    gamma = g / (1 - a)
    poles_mod = closed_loop(plant, mod.state_space()).poles()
    # the exact inverse cancels the plant pole (a pole-zero pair at z = a remains)
    nontrivial = poles_mod[(np.abs(poles_mod - a) > 1e-6) & (np.abs(poles_mod) > 1e-9)]
    assert nontrivial.size == delay
    np.testing.assert_allclose(np.abs(nontrivial), (k * gamma) ** (1 / delay), rtol=1e-6)


def test_collocated_gain_selects_inner_planes():
    k = collocated_gain(0.4, blocks=2)
    assert k.shape == (8, 16)
    assert k[0, 2] == 0.4 and k[1, 3] == 0.4 and k[2, 4] == 0.4 and k[3, 5] == 0.4
    assert k[4, 10] == 0.4 and np.count_nonzero(k) == 8
