"""Identification of Markov parameters (eq. 6.34) from known FIR/IIR systems."""

import numpy as np
import pytest
from scipy import signal

from amb_controller.errors import NotIdentifiedError, PeriodSequenceError
from amb_controller.identification import MarkovIdentifier, StepExperiment


def _mimo_iir_markov(n_terms, n_y, n_u, seed):
    """Markov parameters of a random stable MIMO IIR system via scipy.signal.dlsim."""
    rng = np.random.default_rng(seed)
    n_x = 4
    a = rng.normal(size=(n_x, n_x))
    a *= 0.7 / np.max(np.abs(np.linalg.eigvals(a)))
    b, c, d = rng.normal(size=(n_x, n_u)), rng.normal(size=(n_y, n_x)), rng.normal(size=(n_y, n_u))
    markov = np.zeros((n_terms, n_y, n_u))
    for j in range(n_u):
        impulse = np.zeros((n_terms, n_u))
        impulse[0, j] = 1.0
        _, y, _ = signal.dlsim((a, b, c, d, 1.0), impulse)
        markov[:, :, j] = y
    return (a, b, c, d), markov


def _run(identifier, experiment, system, offset, noise, rng, n_periods):
    a, b, c, d = system
    x = np.zeros(a.shape[0])
    for k in range(n_periods):
        u = experiment.command(k)
        y = c @ x + d @ u + offset + noise * rng.normal(size=c.shape[0])
        x = a @ x + b @ u
        identifier.update(k, u, y)


def test_step_experiment_recovers_fir_exactly_without_noise():
    rng = np.random.default_rng(0)
    markov = rng.normal(size=(6, 8, 4))  # exact FIR of order 5, 8 sensors x 4 axes
    offset = rng.normal(size=8)
    ident = MarkovIdentifier(4, 8, order=5)
    exp = StepExperiment(4, range(4), amplitude=20.0, periods_per_step=12)
    u_hist = np.zeros((6, 4))
    for k in range(exp.n_periods + 6):
        u = exp.command(k)
        u_hist[1:] = u_hist[:-1]
        u_hist[0] = u
        y = offset + np.einsum("kij,kj->i", markov, u_hist)
        ident.update(k, u, y)
    result = ident.estimate()
    np.testing.assert_allclose(result.markov, markov, atol=1e-9)
    np.testing.assert_allclose(result.offset, offset, atol=1e-9)
    # residual from the normal equations: cancellation-limited, ~sqrt(eps) of |y|
    assert np.max(result.residual_rms) < 1e-7 * 20.0 * np.abs(markov).sum(axis=(0, 2)).max()


def test_iir_system_with_noise_within_tolerance():
    # IIR decaying with radius 0.7: order 15 truncation error ~0.7^16 ~ 3e-3 of the gain.
    rng = np.random.default_rng(1)
    system, markov = _mimo_iir_markov(16, 3, 2, seed=2)
    ident = MarkovIdentifier(2, 3, order=15)
    exp = StepExperiment(2, [0, 1], amplitude=1.0, periods_per_step=30)
    # repeat the experiment 10 times to average the noise
    n = 10 * exp.n_periods
    repeated = StepExperiment(2, [0, 1] * 10, amplitude=1.0, periods_per_step=30)
    noise = 0.01
    _run(ident, repeated, system, np.array([0.5, -1.0, 2.0]), noise, rng, n)
    est = ident.estimate()
    scale = np.max(np.abs(markov))
    # LS error ~ noise / sqrt(periods per regressor) ~ 0.01/sqrt(300)*few; plus truncation
    assert np.max(np.abs(est.markov - markov)) < 0.02 * scale
    np.testing.assert_allclose(est.residual_rms, noise, rtol=0.2)


def test_random_excitation_recovers_iir_markov():
    rng = np.random.default_rng(4)
    system, markov = _mimo_iir_markov(25, 2, 2, seed=5)
    a, b, c, d = system
    ident = MarkovIdentifier(2, 2, order=24, fit_offset=False)
    x = np.zeros(a.shape[0])
    for k in range(600):
        u = rng.normal(size=2)
        ident.update(k, u, c @ x + d @ u)
        x = a @ x + b @ u
    np.testing.assert_allclose(ident.estimate().markov, markov, atol=1e-3)


def test_insufficient_excitation_is_reported():
    ident = MarkovIdentifier(2, 1, order=2)
    exp = StepExperiment(2, [0], amplitude=1.0, periods_per_step=10)  # input 1 never moves
    for k in range(40):
        ident.update(k, exp.command(k), np.zeros(1))
    with pytest.raises(NotIdentifiedError, match="excite"):
        ident.estimate()


def test_gap_in_periods_is_refused():
    ident = MarkovIdentifier(1, 1, order=1)
    ident.update(0, np.zeros(1), np.zeros(1))
    with pytest.raises(PeriodSequenceError, match="must be 1"):
        ident.update(2, np.zeros(1), np.zeros(1))


def test_step_experiment_schedule():
    exp = StepExperiment(3, [2, 0], amplitude=5.0, periods_per_step=2, start_period=10)
    cmds = np.array([exp.command(k) for k in range(9, 20)])
    expected = np.zeros((11, 3))
    expected[1:3, 2] = 5.0
    expected[5:7, 0] = 5.0
    np.testing.assert_array_equal(cmds, expected)
    assert exp.n_periods == 8 and exp.done(17) and not exp.done(16)
    assert exp.progress(13) == pytest.approx(0.5)
