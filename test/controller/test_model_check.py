"""A controller its own model says diverges is never set ACTIVE (issue 18, "never worse than PID").

References: the closed-form closed-loop polynomial of eq. 8.10 on a scalar plant with a gain
error (derived in the first test's docstring from eq. 8.12-8.15), and time simulations of the
coefficient-domain loop.
"""

from __future__ import annotations

import numpy as np
import pytest

from amb_controller.basis import control_basis
from amb_controller.config import ConfigError, ControllerConfig
from amb_controller.pipeline import ControllerPipeline
from amb_controller.response import PrescribedResponse
from amb_controller.stability import MAX_MODEL_RADIUS, own_model_radius
from amb_controller.steady_state import ProportionalController
from amb_controller.supervisor import Mode, WaveletControlSupervisor
from amb_controller.synthesis import ForceLimiter
from amb_controller.transient import TransientController

W = V = 0.75
N = 32


@pytest.mark.parametrize("delay", [1, 2])
@pytest.mark.parametrize("r", [1.0, 0.5, 1.6, -1.0])
def test_own_model_radius_is_the_closed_form_of_a_scalar_loop(delay, r):
    """Plant ``g``, inverse ``r / g`` (a gain error r), ``alpha = w / (z - v)``.

    With ``G B_u L = r (1 - alpha (z-1)) / (alpha (z-1) z^i)`` (eq. 8.12 with the controller
    of eq. 8.10; r = 1 gives eq. 8.15's denominator) the closed-loop poles are the roots of
    ``w (z - 1)(z^i - r) + r (z - v)``: for r = 1, i = 1 they are 0 and 2/3; for r = -1 (a
    sign error) 0 and 4/3.
    """
    g = 2e-5
    controller = TransientController(
        np.array([[[r / g]]]), PrescribedResponse.exponential(W, V), delay
    )
    poly = np.polyadd(np.polymul([W, -W], np.r_[1.0, np.zeros(delay - 1), -r]), [r, -r * V])
    expected = np.abs(np.roots(poly)).max()
    assert own_model_radius(np.array([[[g]]]), controller) == pytest.approx(expected, rel=1e-9)


def test_a_controller_without_a_realisation_is_not_checked():
    class OpenLoop:  # e.g. the influence-coefficient baseline (eq. B.1)
        pass

    assert own_model_radius(np.zeros((2, 1, 1)), OpenLoop()) is None


def _setup():
    basis = control_basis("haar", N, [1], n_axes=1, quadratures=["even"])
    limiter = ForceLimiter(basis, limit=1000.0, capacity=1000.0)
    markov = np.array([0.3, 0.5, 0.2]).reshape(3, 1, 1) * 1e-5  # m per coefficient
    return limiter, markov


def _controller(gain_error: float, delay: int = 1):
    """eq. 8.10 with the inverse of the static gain sum(markov), times ``gain_error``."""
    return TransientController(
        np.array([[[gain_error / 1e-5]]]), PrescribedResponse.exponential(W, V), delay
    )


def _loop(sup, markov, n_periods=80, disturbance=50.0):
    """Coefficient-domain plant ``Q[k] = sum_j A_j (F + U)[k - j]`` under ``sup``."""
    u = np.zeros(n_periods + 10)
    q = np.zeros(n_periods)
    for k in range(n_periods):
        q[k] = sum(markov[j, 0, 0] * (disturbance + u[k - j]) for j in range(min(k + 1, 3)))
        cmd = sup.step(k, np.array([q[k]]))
        u[cmd.target_period] = cmd.coefficients[0]
    return q, u[:n_periods]


def test_a_controller_that_diverges_on_its_own_model_is_refused_and_the_loop_stays_pid():
    limiter, markov = _setup()
    bad = _controller(-1.0)  # a sign error: the loop on this very model diverges
    radius = own_model_radius(markov, bad)
    assert radius > 1.0
    # evidence from a time simulation, the check raised above the radius: the loop runs away
    sup = WaveletControlSupervisor(limiter, delay=1, max_radius=10.0)
    sup.set_controller(bad, radius)
    assert sup.set_mode(Mode.ACTIVE)[0]
    q, _ = _loop(sup, markov)
    pid_only = 50.0 * markov.sum()  # the disturbance's response without the added force
    assert abs(q[-1]) > 10 * pid_only  # runs away until the force limit (1000 N) holds it
    # with the default check it is refused, says why, and adds no force
    sup = WaveletControlSupervisor(limiter, delay=1)
    sup.set_controller(_controller(-1.0), radius)
    ok, why = sup.set_mode(Mode.ACTIVE)
    assert not ok and sup.mode == Mode.OFF
    assert f"{radius:.3f}" in why and "max_model_radius 0.98" in why and "diverge" in why
    assert "ACTIVE refused" in sup.message
    q, u = _loop(sup, markov)
    assert not np.any(u) and q[-1] == pytest.approx(pid_only, rel=1e-12)


def test_a_slow_loop_below_one_is_refused_too_and_a_good_one_runs():
    limiter, markov = _setup()
    slow = _controller(0.02)  # 2 % of the needed gain: the loop decays by ~1.5 % per period
    radius = own_model_radius(markov, slow)
    assert MAX_MODEL_RADIUS <= radius < 1.0
    sup = WaveletControlSupervisor(limiter, delay=1)
    sup.set_controller(slow, radius)
    ok, why = sup.set_mode(Mode.ACTIVE)
    assert not ok and "hardly decay" in why
    good = _controller(1.0)
    sup.set_controller(good, own_model_radius(markov, good))
    assert sup.set_mode(Mode.ACTIVE)[0]
    q, _ = _loop(sup, markov)
    assert abs(q[-1]) < 1e-3 * abs(q[2])  # the disturbance is cancelled


def test_a_new_unsafe_controller_switches_a_running_one_off():
    limiter, markov = _setup()
    sup = WaveletControlSupervisor(limiter, delay=1)
    good = _controller(1.0)
    sup.set_controller(good, own_model_radius(markov, good))
    assert sup.set_mode(Mode.ACTIVE)[0]
    _loop(sup, markov, n_periods=10)
    bad = _controller(-1.0)
    sup.set_controller(bad, own_model_radius(markov, bad))
    assert sup.mode == Mode.OFF and sup.message.startswith("off: closed loop on its own model")


def _model(markov, inverse):
    from amb_controller.model_file import WaveletModel

    return WaveletModel(
        markov=markov, inverse=inverse, wavelet="haar", samples_per_rev=16,
        omega=2 * np.pi * 20, levels=(1,),
    )  # fmt: skip


def test_the_pipeline_checks_every_model_it_is_given():
    config = ControllerConfig(samples_per_rev=16)  # 4 inner sensors, both quadratures: 8 x 8
    n = 8
    markov = np.zeros((2, n, n))
    markov[1] = 1e-5 * np.eye(n)  # one period of delay
    inverse = np.zeros((config.inverse_order + 1, n, n))
    inverse[0] = -1e5 * np.eye(n)  # a model file whose inverse has the wrong sign
    pipe = ControllerPipeline(config, 1000.0, model=_model(markov, inverse))
    assert pipe.supervisor.radius > 1.0
    ok, why = pipe.set_mode(Mode.ACTIVE)
    assert not ok and "spectral radius" in why
    assert pipe.status()["message"].startswith("off: ACTIVE refused")
    inverse[0] *= -1.0
    pipe.set_model(_model(markov, inverse))
    assert pipe.supervisor.radius < MAX_MODEL_RADIUS
    assert pipe.set_mode(Mode.ACTIVE)[0]
    # a proportional controller is checked the same way (eq. 7.7 has a realisation)
    prop = ControllerPipeline(
        ControllerConfig(samples_per_rev=16, controller="proportional", gain=2.5),
        1000.0,
        model=_model(markov, inverse),
    )
    assert isinstance(prop.supervisor.controller, ProportionalController)
    # -k z^-2 (delay 2) around z^-1: 1 + k z^-3 = 0, |z| = k^(1/3)
    assert prop.supervisor.radius == pytest.approx(2.5 ** (1 / 3), rel=1e-9)
    assert not prop.set_mode(Mode.ACTIVE)[0]


def test_max_model_radius_is_validated():
    with pytest.raises(ConfigError, match="max_model_radius"):
        ControllerConfig(max_model_radius=0.0)
    with pytest.raises(ConfigError, match="max_model_radius"):
        ControllerConfig(max_model_radius=float("nan"))
    assert ControllerConfig(max_model_radius=1.5).max_model_radius == 1.5
    assert ControllerConfig(max_model_radius=float("inf")).max_model_radius == float("inf")
