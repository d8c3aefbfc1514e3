"""ControllerPipeline: configuration checks, period assembly against PyWavelets, gaps."""

import numpy as np
import pytest
import pywt

from amb_controller.config import ConfigError, ControllerConfig
from amb_controller.model_file import WaveletModel
from amb_controller.pipeline import ControllerPipeline
from amb_controller.supervisor import Mode
from amb_controller.synthesis import synthesize
from amb_wavelet.analysis import AnalysisFilterbank
from amb_wavelet.frontend import ChannelFrontEnd

N = 32
CAPACITY = 1000.0


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("w", 1.2),
        ("v", 1.0),
        ("delay_periods", 0),
        ("controller", "pid"),
        ("levels", [0]),
        ("samples_per_rev", 48),
        ("frames", ["rotating"]),
        ("sensors", [8]),
        ("wavelet", "bior2.2"),
    ],
)
def test_config_errors_name_the_field_and_value(field, value):
    with pytest.raises(ConfigError, match=f"'{field}' = "):
        ControllerConfig.from_dict({field: value})


def test_force_limit_above_the_bearing_capacity_is_refused():
    with pytest.raises(ConfigError, match=r"force_limit.*\(0, 1000\] N"):
        ControllerConfig.from_dict({"force_limit": 1200.0}, capacity=CAPACITY)
    cfg = ControllerConfig.from_dict({"force_limit": 400.0}, capacity=CAPACITY)
    assert cfg.force_limit == (400.0,) * 4
    with pytest.raises(ConfigError, match="unknown"):
        ControllerConfig.from_dict({"gain_k": 1.0})


def _signal(n_samples, seed=0):
    """1 x and 2 x orbits plus a little broadband content, 8 channels (m)."""
    rng = np.random.default_rng(seed)
    n = np.arange(n_samples)
    th = 2 * np.pi * n / N
    amp = rng.uniform(1e-5, 5e-5, 8)
    ph = rng.uniform(0, 2 * np.pi, 8)
    x = amp * np.cos(th[:, None] + ph) + 0.3 * amp * np.sin(2 * th[:, None] - ph)
    return x + 1e-6 * rng.standard_normal(x.shape), th


def _run(pipeline, x, th, skip=()):
    front = ChannelFrontEnd(N)
    bank = AnalysisFilterbank(pipeline.config.wavelet, 6, front.n_channels)
    measured, commands = {}, []
    for n in range(x.shape[0]):
        if n in skip:
            continue
        if n - 1 in skip:  # the filterbank node resets at a gap
            front.reset()
            bank.reset(n)
        command = pipeline.on_sample(n, bank.step(front.step(x[n], th[n]), n), x[n])
        if command is not None:
            commands.append(command)
            measured[command.based_on_period] = pipeline.last_measured
    return measured, commands


def test_measured_vector_equals_pywavelets_per_period():
    cfg = ControllerConfig(samples_per_rev=N, levels=(1, 2), sensors=tuple(range(8)))
    pipe = ControllerPipeline(cfg, CAPACITY)
    x, th = _signal(6 * N)
    measured, commands = _run(pipe, x, th)
    assert [c.target_period for c in commands] == [k + 2 for k in range(6)]
    d = N // 4
    for k in range(1, 6):
        even = pywt.wavedec(x[k * N : (k + 1) * N], "haar", mode="periodization", level=5, axis=0)
        odd = pywt.wavedec(
            x[k * N - d : (k + 1) * N - d], "haar", mode="periodization", level=5, axis=0
        )
        # layout: level p, translation q, quadrature, channel
        expected = np.concatenate(
            [even[1][0], odd[1][0], even[2][0], odd[2][0], even[2][1], odd[2][1]]
        )
        np.testing.assert_allclose(measured[k], expected, rtol=1e-12, atol=1e-18)
    # OFF: every command has zero force and is for m + delay
    assert all(np.all(c.force == 0) and c.mode == Mode.OFF for c in commands)


def _toy_model(cfg, pipe):
    """A static square plant: measured = 1e-6 m per N (collocated), for the gap test."""
    n_y, n_u = pipe.measured.n_coefficients, pipe.control.n_coefficients
    markov = np.zeros((3, n_y, n_u))
    markov[1, :, :] = 1e-6 * np.eye(n_y, n_u)
    return WaveletModel(markov, np.zeros((1, n_u, n_y)), cfg.wavelet, N, 60.0, cfg.levels)


def _active_toy() -> ControllerPipeline:
    """A proportional controller ACTIVE on the toy model."""
    cfg = ControllerConfig(samples_per_rev=N, controller="proportional", gain=0.3)
    pipe = ControllerPipeline(cfg, CAPACITY)
    pipe.set_model(_toy_model(cfg, pipe))
    assert pipe.set_mode(Mode.ACTIVE) == (True, "active")
    return pipe


def test_gap_gives_a_zero_hold_command_and_never_mixes_periods():
    pipe = _active_toy()
    x, th = _signal(8 * N)
    measured, commands = _run(pipe, x, th, skip={3 * N + 5})
    by_period = {c.based_on_period: c for c in commands}
    # one command per period, including the broken one
    assert sorted(by_period) == list(range(8))
    broken = by_period[3]
    assert broken.hold and np.all(broken.force == 0) and "gap" in broken.message
    assert measured[3] is None
    # the periods after the gap are complete again and the controller acts on them
    assert measured[4] is not None
    assert np.any(by_period[5].force != 0) and not by_period[5].hold
    status = pipe.status()
    assert status["commands_sent"] == 8 and status["mode"] == Mode.ACTIVE


def test_identification_request_must_excite_every_control_coefficient():
    cfg = ControllerConfig(samples_per_rev=N)
    pipe = ControllerPipeline(cfg, CAPACITY)
    ok, message = pipe.start_identification(axes=[0, 1], level=1)
    assert not ok and "every one must be stepped" in message
    ok, message = pipe.start_identification()
    assert ok and pipe.supervisor.mode == Mode.IDENTIFYING


def test_a_period_flagged_missing_up_to_a_sample_is_reported_as_partial():
    # a realtime plant with partial_commands: period 5's command acted from its sample 10 on
    pipe = _active_toy()
    x, th = _signal(8 * N)
    front = ChannelFrontEnd(N)
    bank = AnalysisFilterbank(pipe.config.wavelet, 6, front.n_channels)
    sent = {}
    for n in range(x.shape[0]):
        k, position = divmod(n, N)
        if position == 0 and k == 5:
            sent = pipe.supervisor.applied(5).copy()  # commanded by period 3's step
        flagged = k == 5 and position < 10
        command = pipe.on_sample(
            n, bank.step(front.step(x[n], th[n]), n), x[n], command_missing=flagged
        )
        if command is not None and command.based_on_period == 5:
            applied = pipe.supervisor.applied(5)
    status = pipe.status()
    assert status["commands_late"] == 1 and status["commands_partial"] == 1
    assert np.any(sent != 0)
    # what is recorded as applied is the orthogonal projection, on the control basis, of the
    # force that acted (the sent force from sample 10 on): its residual is orthogonal to every
    # basis waveform (the normal equations), and it is not nothing
    basis = pipe.supervisor.limiter.basis
    acted = synthesize(sent, basis)
    acted[:, :10] = 0.0
    residual = acted - synthesize(applied, basis)
    W = basis.weights.reshape(basis.n_coefficients, -1)
    scale = np.abs(W).max() * np.abs(acted).sum()
    np.testing.assert_allclose(W @ residual.ravel(), 0.0, atol=1e-12 * scale)
    assert 0 < np.linalg.norm(synthesize(applied, basis)) <= np.linalg.norm(acted) * (1 + 1e-12)
