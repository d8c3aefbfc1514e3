"""
Transient controller (eq. 8.10): difference equation, realisation and exact closed-loop poles.

References: scipy.signal.lfilter of hand-derived closed-loop transfer functions,
numpy.roots of hand-expanded characteristic polynomials.
"""

import numpy as np
import pytest
from scipy import signal

from amb_controller.errors import PeriodSequenceError, ShapeError
from amb_controller.inverse import pseudo_inverse_series
from amb_controller.lti import fir_state_space
from amb_controller.response import PrescribedResponse
from amb_controller.stability import closed_loop, nominal_poles, spectral_radius
from amb_controller.transient import TransientController


def _run_loop(controller, markov, disturbance):
    """Simulate Q[k] = sum_j A_j (F + U)[k-j], U from the controller (delay honoured)."""
    n_periods = disturbance.shape[0]
    n_y, n_u = markov.shape[1:]
    applied = np.zeros((n_periods + controller.delay + 1, n_u))
    q = np.zeros((n_periods, n_y))
    for k in range(n_periods):
        for j in range(min(k + 1, markov.shape[0])):
            q[k] += markov[j] @ (disturbance[k - j] + applied[k - j])
        cmd = controller.step(k, q[k])
        applied[cmd.target_period] = cmd.coefficients
    return q


@pytest.mark.parametrize("delay", [1, 2, 3])
@pytest.mark.parametrize(("w", "v"), [(0.75, 0.75), (0.9, 0.8)])
def test_scalar_loop_step_response_matches_hand_transfer_function(delay, w, v):
    # Static plant g, exact inverse 1/g, step disturbance F[k] = 1 (k >= 0):
    # Q(z) = g w / (w - w z^-1 ... ) = g * w / p(z^-1) with
    # p = z^-i (1 - v z^-1) + w (1 - z^-1)(1 - z^-i)      (derived in the module doc)
    g = 1.7
    ctrl = TransientController(
        np.full((1, 1, 1), 1 / g), PrescribedResponse.exponential(w, v), delay
    )
    n = 60
    q = _run_loop(ctrl, np.full((1, 1, 1), g), np.ones((n, 1)))
    x = np.zeros(delay + 2)
    x[delay] += 1
    x[delay + 1] -= v
    p = x + w * np.convolve([1, -1], np.r_[1, np.zeros(delay - 1), -1])
    impulse = np.zeros(n)
    impulse[0] = 1
    expected = g * signal.lfilter([w], p, impulse)
    np.testing.assert_allclose(q[:, 0], expected, rtol=1e-10, atol=1e-12)
    assert abs(q[-1, 0]) < 1e-3 * g  # integral action removes the steady state


def test_state_space_loop_matches_hand_transfer_function():
    # The same loop as above through the realisation: closed_loop(plant, controller).
    g, w, v = 2.0, 0.6, 0.5
    alpha = PrescribedResponse.exponential(w, v)
    ctrl = TransientController(np.full((1, 1, 1), 1 / g), alpha, 1)
    loop = closed_loop(fir_state_space(np.full((1, 1, 1), g)), ctrl.state_space())
    # delay-1 loop: Q = g w / p, p = [w, 1 - 2w, w - v] (z^-1 ascending)
    q = loop.simulate(np.ones((30, 1)))[:, 0]
    impulse = np.r_[1.0, np.zeros(29)]
    np.testing.assert_allclose(
        q, g * signal.lfilter([w], [w, 1 - 2 * w, w - v], impulse), atol=1e-12
    )


def test_difference_equation_equals_state_space_realisation():
    rng = np.random.default_rng(5)
    n_y, n_u, order = 6, 3, 5
    inv = rng.normal(size=(order + 1, n_u, n_y))
    alphas = [PrescribedResponse.exponential(0.75, 0.75)] * 3 + [
        PrescribedResponse.linear_decay(0.2)
    ] * 3
    ctrl = TransientController(inv, alphas, delay=2)
    q = rng.normal(size=(40, n_y))
    stepped = np.array([ctrl.step(k, q[k]).coefficients for k in range(40)])
    applied = ctrl.state_space().simulate(q)
    # state_space includes z^-2: the command computed at k is applied at k + 2
    np.testing.assert_allclose(applied[2:], stepped[:-2], atol=1e-12)
    np.testing.assert_allclose(applied[:2], 0.0)


def test_chunked_equals_batch_after_state_copy_and_reset():
    rng = np.random.default_rng(6)
    inv = rng.normal(size=(4, 2, 3))
    ctrl = TransientController(inv, PrescribedResponse.exponential(0.8, 0.7), 1)
    q = rng.normal(size=(20, 3))
    batch = [ctrl.step(k, q[k]).coefficients for k in range(20)]
    ctrl.reset()
    first = [ctrl.step(k, q[k]).coefficients for k in range(10)]
    saved = ctrl.get_state()
    second = [ctrl.step(k, q[k]).coefficients for k in range(10, 20)]
    np.testing.assert_allclose(np.array(first + second), np.array(batch), atol=1e-13)
    ctrl.set_state(saved)
    again = [ctrl.step(k, q[k]).coefficients for k in range(10, 20)]
    np.testing.assert_allclose(again, second, atol=1e-13)


def test_exact_poles_of_scalar_dynamic_loop_match_hand_polynomial():
    # Plant G = a0 + a1 z^-1, inverse B0 + B1 z^-1 (truncated), beta = n(x)/d(x), delay i.
    # Loop: 1 + x^i G(x) B(x) n(x)/d(x) = 0  ->  d(x) + x^i G(x) B(x) n(x) = 0.
    a = np.array([0.4, 1.0])
    inv = pseudo_inverse_series(a.reshape(2, 1, 1), order=1)
    alpha = PrescribedResponse.exponential(0.75, 0.75)
    delay = 2
    ctrl = TransientController(inv, alpha, delay)
    loop = closed_loop(fir_state_space(a.reshape(2, 1, 1)), ctrl.state_space())
    n, d = alpha.beta()
    char = np.polyadd(
        np.r_[d, np.zeros(delay + 2)],
        np.r_[np.zeros(delay), np.convolve(np.convolve(a, inv[:, 0, 0]), n)],
    )
    char = np.trim_zeros(char, "b")
    expected = np.roots(char)
    poles = loop.poles()
    poles = poles[np.abs(poles) > 1e-9]
    expected = expected[np.abs(expected) > 1e-9]
    np.testing.assert_allclose(np.sort_complex(poles), np.sort_complex(expected), atol=1e-8)


def test_exact_check_catches_truncation_instability_that_nominal_analysis_misses():
    # A non-minimum-phase plant has no stable causal inverse: the order-5 least-squares
    # inverse is poor, so the real loop differs from the nominal one of eq. 8.9.
    # G = 1 - 1.5 z^-1: the step response reverses sign (zero at z = 1.5).
    a = np.array([1.0, -1.5]).reshape(2, 1, 1)
    alpha = PrescribedResponse.exponential(0.75, 0.75)
    nominal = np.max(np.abs(nominal_poles(alpha, 2)))
    ctrl = TransientController(pseudo_inverse_series(a, order=5), alpha, 2)
    loop = closed_loop(fir_state_space(a), ctrl.state_space())
    radius = spectral_radius(loop)
    assert nominal < 1.0 < radius
    # and the time simulation indeed diverges at that rate
    q = _run_loop(ctrl, a, np.ones((200, 1)))
    growth = (abs(q[-1, 0]) / abs(q[-41, 0])) ** (1 / 40)
    assert growth == pytest.approx(radius, rel=0.02)


def test_mimo_loop_with_tall_plant_settles():
    # 4 sensors, 2 axes, exact left inverse: nominal behaviour on the controlled subspace.
    rng = np.random.default_rng(11)
    g = rng.normal(size=(4, 2))
    inv = pseudo_inverse_series(g[None], order=0)
    ctrl = TransientController(inv, PrescribedResponse.exponential(0.75, 0.75), 2)
    q = _run_loop(ctrl, g[None], np.tile([1.0, -0.5], (60, 1)))
    assert np.max(np.abs(q[-1])) < 1e-5 * np.max(np.abs(q[0]))
    loop = closed_loop(fir_state_space(g[None]), ctrl.state_space())
    assert spectral_radius(loop) == pytest.approx(np.sqrt(1 / 3), rel=1e-6)


def test_step_validates_inputs():
    ctrl = TransientController(np.ones((2, 1, 2)), PrescribedResponse.exponential(0.5, 0.5), 1)
    with pytest.raises(ShapeError, match=r"shape \(2,\)"):
        ctrl.step(0, np.ones(3))
    ctrl.step(0, np.ones(2))
    with pytest.raises(PeriodSequenceError, match="must be 1"):
        ctrl.step(3, np.ones(2))
    with pytest.raises(ValueError, match="delay"):
        TransientController(np.ones((1, 1, 1)), PrescribedResponse.exponential(0.5, 0.5), 0)
