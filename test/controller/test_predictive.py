"""Receding-horizon controller on Markov parameters (issue 18 item 2, amb_controller.predictive).

References: closed forms of the scalar loop (derived in each test's docstring from (P1)-(P4)
of the module), deadbeat sequences of a static plant, and time simulations of the
coefficient-domain loop with a model error.
"""

from __future__ import annotations

import numpy as np
import pytest

from amb_controller.basis import control_basis
from amb_controller.config import ConfigError, ControllerConfig
from amb_controller.errors import ControllerValueError
from amb_controller.predictive import PredictiveController, predictive_gain
from amb_controller.stability import own_model_radius
from amb_controller.supervisor import Mode, WaveletControlSupervisor
from amb_controller.synthesis import ForceLimiter


@pytest.mark.parametrize("horizon", [1, 2, 5, 20])
@pytest.mark.parametrize(("g0", "g1"), [(1.0, -1.3), (1.0, 0.5), (2e-5, 3e-5)])
def test_the_loop_pole_on_a_first_order_fir_model_is_the_closed_form(horizon, g0, g1):
    """Model ``g0 + g1 z^-1``, i = 1, C = 1, no move weight.

    (P2): ``q^_0 = g0 u + g1 u[k] + d^``, ``q^_h = G u + d^`` for h >= 1 (``G = g0 + g1``), so
    the minimiser of (P3) is ``u = -(g0 (g1 u[k] + d^) + (P-1) G d^) / (g0^2 + (P-1) G^2)``. On
    its own model ``d^`` is the true (constant) disturbance and the loop is
    ``u[k+1] = a u[k] + const`` with ``a = -g0 g1 / (g0^2 + (P-1) G^2)``; the FIR and the
    controller's other states add poles at 0. P = 1 is the model's inverse: its pole is the
    model's zero ``-g1/g0`` (1.3 for 1 - 1.3 z^-1, outside the unit circle); a long horizon
    pulls it in (mean-level control).
    """
    markov = np.array([g0, g1]).reshape(2, 1, 1)
    controller = PredictiveController(markov, 1, horizon, 1, 0.0, 0.0)
    big_g = g0 + g1
    expected = abs(g0 * g1 / (g0**2 + (horizon - 1) * big_g**2))
    assert own_model_radius(markov, controller) == pytest.approx(expected, rel=1e-9)


@pytest.mark.parametrize("delay", [1, 2, 3])
def test_a_static_plant_is_cancelled_deadbeat_after_the_delay(delay):
    """Static model ``g``, P = C = 1: ``u[k+i] = -d^[k] / g``. The command made at the end of
    period 0, the first to see a step ``d``, acts over period i: ``q = d`` for k < i, 0 after."""
    g, d = 3e-5, 2.0e-4
    controller = PredictiveController(np.array([[[g]]]), delay, 1, 1, 0.0, 0.0)
    u = np.zeros(30)
    q = np.zeros(20)
    for k in range(20):
        q[k] = g * u[k] + d
        step = controller.step(k, np.array([q[k]]))
        assert step.target_period == k + delay
        u[step.target_period] = step.coefficients[0]
    np.testing.assert_allclose(q[:delay], d, rtol=1e-12)
    np.testing.assert_allclose(q[delay:], 0.0, atol=1e-12 * d)
    np.testing.assert_allclose(u[delay:20], -d / g, rtol=1e-12)


def _rotation(deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, -s], [s, c]])


def _lightly_damped_model(n_terms=12):
    """A 1 x coefficient pair (even, odd) of a resonance: ``A_j = g r^j R(j theta)``."""
    return np.stack([2e-6 * 0.8**j * _rotation(25.0 * j) for j in range(n_terms)])


@pytest.mark.parametrize(("gain", "phase"), [(1.0, 0.0), (1.3, 0.0), (0.7, 30.0), (1.3, -30.0)])
def test_it_is_offset_free_with_a_model_error(gain, phase):
    """The plant is the model times ``gain`` and rotated by ``phase`` (the robustness targets'
    +-30 %, +-30 degrees): a step disturbance is removed completely (the disturbance estimate
    (P1) is the integral action). P = 5: on this resonance mean-level control (P = 20) is not
    robust to 1.3 at -30 degrees (radius 1.006 on the true plant); the shorter horizon is."""
    model = _lightly_damped_model()
    plant = gain * np.einsum("ab,kbc->kac", _rotation(phase), model)
    controller = PredictiveController(model, 1, 5, 1, 0.0, 0.0)
    n = 120
    u = np.zeros((n + 2, 2))
    q = np.zeros((n, 2))
    d = np.array([3e-4, -1e-4])
    for k in range(n):
        q[k] = d + sum(plant[j] @ u[k - j] for j in range(min(k + 1, len(plant))))
        u[k + 1] = controller.step(k, q[k]).coefficients
    assert np.linalg.norm(q[-1]) < 1e-6 * np.linalg.norm(d)
    assert own_model_radius(plant, controller) < 1.0


def test_its_realisation_gives_the_commands_of_its_steps():
    rng = np.random.default_rng(3)
    model = rng.normal(size=(4, 3, 2)) * 1e-5
    controller = PredictiveController(model, 2, 8, 2, 0.1, 0.05)
    ss = controller.state_space()
    q = rng.normal(size=(15, 3)) * 1e-4
    commands = np.zeros((17, 2))
    for k in range(15):
        step = controller.step(k, q[k])
        commands[step.target_period] = step.coefficients
    np.testing.assert_allclose(ss.simulate(q), commands[:15], atol=1e-12 * np.abs(commands).max())


def test_a_move_weight_slows_the_command():
    """``rho`` penalises the change of the command: the first move after a step is smaller."""
    markov = np.array([[[3e-5]]])
    first = [
        PredictiveController(markov, 1, 1, 1, weight, 0.0).step(0, np.array([1e-4])).coefficients[0]
        for weight in (0.0, 1.0, 3.0)
    ]
    # (P3) with P = C = 1 on a static g: u = -g d / (g^2 + rho^2), rho = weight g
    np.testing.assert_allclose(first, [-1e-4 / 3e-5 / (1 + w**2) for w in (0, 1, 3)], rtol=1e-12)


def test_the_input_weight_is_a_tikhonov_term_in_steady_state():
    """Static ``g``, P = 3, C = 1, no move weight: the command held over the horizon minimises
    ``3 ((g u + d)^2 + sigma^2 u^2)`` with ``sigma = input_weight g``, so ``u = -g d / (g^2 +
    sigma^2)`` and the steady offset is ``d sigma^2 / (g^2 + sigma^2)``."""
    g, d = 3e-5, 1e-4
    for weight in (0.0, 0.03, 0.5):
        step = PredictiveController(np.array([[[g]]]), 1, 3, 1, 0.0, weight).step(0, np.array([d]))
        np.testing.assert_allclose(step.coefficients, [-d / g / (1 + weight**2)], rtol=1e-12)
    with pytest.raises(ControllerValueError, match="input_weight"):
        predictive_gain(np.ones((1, 1, 1)), 1, 2, 1, 0.0, -0.1)


def test_bad_settings_are_refused_with_the_reason():
    markov = np.ones((2, 1, 1))
    with pytest.raises(ControllerValueError, match="moves"):
        predictive_gain(markov, 1, 2, 3, 0.0, 0.0)
    with pytest.raises(ControllerValueError, match="move_weight"):
        predictive_gain(markov, 1, 2, 1, -1.0, 0.0)
    with pytest.raises(ControllerValueError, match="no unique minimiser"):
        predictive_gain(np.zeros((2, 1, 2)), 1, 4, 1, 0.0, 0.0)
    with pytest.raises(ConfigError, match="moves"):
        ControllerConfig(controller="predictive", horizon=4, moves=5)


def _supervised(delay, limit):
    basis = control_basis("haar", 16, [1], n_axes=1, quadratures=["even"])
    limiter = ForceLimiter(basis, limit=limit, capacity=1000.0)
    sup = WaveletControlSupervisor(limiter, delay=delay)
    return sup


def _active_law(g, delay, limit):
    """The supervisor ACTIVE with the deadbeat law of the static plant ``q = g u``."""
    sup = _supervised(delay, limit)
    controller = PredictiveController(np.array([[[g]]]), delay, 1, 1, 0.0, 0.0)
    sup.set_controller(controller, own_model_radius(np.array([[[g]]]), controller))
    assert sup.set_mode(Mode.ACTIVE)[0]
    return sup


def _run(sup, g, disturbance, missing=()):
    """Static plant ``q = g (u + d[k])`` under ``sup``; ``missing`` periods apply no command."""
    n = len(disturbance)
    u = np.zeros(n + 5)
    q = np.zeros(n)
    for k in range(n):
        if k in missing:
            sup.command_missing(k)
            u[k] = 0.0
        q[k] = g * (u[k] + disturbance[k])
        cmd = sup.step(k, np.array([q[k]]))
        u[cmd.target_period] = cmd.coefficients[0]
    return q, u[:n]


def test_a_saturated_command_does_not_wind_it_up():
    """A disturbance needing 3 x the force limit, then gone: the controller knows the limited
    force was applied (``record_applied``), so once the disturbance goes, the next command it
    can act on cancels the rest exactly: no overshoot the held integrator would bring."""
    g, delay = 1e-5, 1
    sup = _active_law(g, delay, limit=50.0)
    need = 3 * 50.0 * np.sqrt(16)  # coefficient (N sqrt(samples)) of 3 x the limit
    d = np.r_[np.full(20, need), np.zeros(20)]
    q, u = _run(sup, g, d)
    coefficient_limit = np.abs(u[5:20]).max()
    assert coefficient_limit < need  # it saturated
    np.testing.assert_allclose(u[5:20], -coefficient_limit, rtol=1e-9)  # held at the limit
    # the disturbance drops at 20: q[20] sees the old command, then all is cancelled
    np.testing.assert_allclose(q[21 + delay :], 0.0, atol=1e-9 * g * need)


def test_a_lost_command_is_not_mistaken_for_a_disturbance():
    """Period 10's command never reached the plant: the controller is told it was zero, so its
    estimate stays the true disturbance and the next periods are cancelled again."""
    g, delay = 1e-5, 2
    sup = _active_law(g, delay, limit=1000.0)
    d = np.full(30, 40.0)
    q, _ = _run(sup, g, d, missing=(10,))
    np.testing.assert_allclose(q[10], g * 40.0, rtol=1e-12)  # the lost period sees it all
    tol = 1e-9 * g * 40.0
    np.testing.assert_allclose(q[delay:10], 0.0, atol=tol)
    np.testing.assert_allclose(q[11:], 0.0, atol=tol)


def test_a_replaced_command_is_what_the_law_records_as_applied():
    """The early action's hold of the law (``WaveletControlSupervisor.replace_command``): the
    command for period 11 is replaced by zero after the law made it. The plant applies the
    zero, so q[11] sees the whole disturbance; the law, told so, keeps its estimate the true
    disturbance and cancels every later period exactly (as after a lost command). A supervisor
    whose controller is not told the applied inputs refuses a replacement."""
    g, delay = 1e-5, 1
    sup = _active_law(g, delay, limit=1000.0)
    d = np.full(30, 40.0)
    u = np.zeros(35)
    q = np.zeros(30)
    for k in range(30):
        q[k] = g * (u[k] + d[k])
        cmd = sup.step(k, np.array([q[k]]))
        if cmd.target_period == 11:
            cmd = sup.replace_command(cmd, np.zeros(1))
            assert not cmd.force.any() and sup.sent(11)[0] == 0.0
        u[cmd.target_period] = cmd.coefficients[0]
    tol = 1e-9 * g * 40.0
    np.testing.assert_allclose(q[11], g * 40.0, rtol=1e-12)
    np.testing.assert_allclose(q[delay:11], 0.0, atol=tol)
    np.testing.assert_allclose(q[12:], 0.0, atol=tol)
    bare = _supervised(delay, limit=1000.0)
    off = bare.step(0, np.zeros(1))
    with pytest.raises(ControllerValueError, match="applied inputs"):
        bare.replace_command(off, np.zeros(1))
