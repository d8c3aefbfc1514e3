"""
The 150 N step at the third critical speed: is the wavelet-domain model right there?

Reference: the plant simulator itself (the FE rotor under PID, the nonlinear AMB law,
the coil amplifier), driven noise-free with a step in one Haar control coefficient; the
measured coefficients are those of the measurement basis over the simulated displacement.
The FE-route Markov parameters must predict that step response (their running sum). Then
the exact closed-loop spectral radius on that model says which sensor set can work.
"""

import math
from dataclasses import replace

import numpy as np
import pytest

from amb_controller.basis import control_basis
from amb_controller.config import ControllerConfig
from amb_controller.lti import fir_state_space
from amb_controller.response import PrescribedResponse
from amb_controller.selection import selected_measurement_basis
from amb_controller.stability import closed_loop, spectral_radius
from amb_controller.transient import TransientController

SPR = 32
ROOT_SCENARIO = "sync_force_150N_third_critical.yaml"


@pytest.fixture(scope="module")
def third(rig):
    from amb_plant_sim.scenario import load_scenario

    from .conftest import SCENARIOS

    return load_scenario(SCENARIOS / ROOT_SCENARIO, rig)


def _simulated_step(rig, scenario, cfg, j, amplitude, n_settle=8, n_step=60):
    from amb_plant_sim.simulator import PlantSimulator

    cb = control_basis(cfg.wavelet, SPR, cfg.levels, 4)
    mb = selected_measurement_basis(cfg)
    quiet = replace(scenario, events=(), measurement_noise=0.0)
    sim = PlantSimulator(rig, quiet, SPR, 0)
    u = np.zeros(cb.n_coefficients)
    u[j] = amplitude
    step_force = np.tensordot(u, cb.weights, axes=1).T
    blocks = [
        sim.advance(SPR, step_force if k >= n_settle else np.zeros((SPR, 4))).displacement
        for k in range(n_settle + n_step)
    ]
    x = np.concatenate(blocks)
    length, off = mb.weights.shape[2], mb.offset
    q = np.array(
        [
            np.tensordot(mb.weights, x[k * SPR + off : k * SPR + off + length].T, 2)
            for k in range(n_settle - 1, n_settle + n_step)
        ]
    )
    return q[1:] - q[0]


def test_fe_markov_parameters_predict_the_simulated_step_at_the_third_critical(rig, third):
    from amb_apps.closed_loop import fe_model

    cfg = ControllerConfig(samples_per_rev=SPR, levels=(1, 2, 3), delay_periods=1)
    model = fe_model(rig, 2 * math.pi * third.speed_hz, cfg, n_terms=60)
    labels = control_basis("haar", SPR, (1, 2, 3)).labels
    for label in ("p1/q1/even/c0", "p2/q1/odd/c1", "p3/q2/even/c2"):
        j = labels.index(label)
        sim = _simulated_step(rig, third, cfg, j, 20.0)
        predicted = np.cumsum(model.markov[: len(sim), :, j], axis=0) * 20.0
        scale = np.abs(predicted).max()
        assert scale > 1e-7  # m sqrt(samples): the step is seen
        np.testing.assert_allclose(sim, predicted, rtol=0, atol=0.05 * scale, err_msg=label)


def test_inner_sensor_loop_is_unstable_on_the_model_and_all_sensors_are_not(rig, third):
    from amb_apps.closed_loop import fe_model

    omega = 2 * math.pi * third.speed_hz
    alpha = PrescribedResponse.exponential(0.75, 0.75)
    radius = {}
    for name, sensors in (("inner", (2, 3, 4, 5)), ("all", tuple(range(8)))):
        cfg = ControllerConfig(samples_per_rev=SPR, delay_periods=1, sensors=sensors)
        model = fe_model(rig, omega, cfg, n_terms=40)
        ctl = TransientController(model.inverse, alpha, 1)
        radius[name] = spectral_radius(
            closed_loop(fir_state_space(model.markov), ctl.state_space())
        )
        if name == "inner":
            sv = np.linalg.svd(model.markov.sum(axis=0), compute_uv=False)
            assert sv[-1] < 0.01 * sv[0]  # G(1) nearly singular at the inner sensors
    assert radius["inner"] > 1.0
    assert radius["all"] < 0.9
