"""The sinusoidal control force (``output_basis = "sinusoid"``, issue 18 item 3).

References: the closed-form waveforms sqrt(2/N) cos / sin, numpy's FFT of the force each command
carries, and the harmonic content of the displacement against the Haar square-wave force.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from amb_controller.basis import control_basis
from amb_controller.config import ConfigError, ControllerConfig
from amb_controller.fourier_basis import sinusoid_control_basis
from amb_controller.selection import control_waveform, selected_control_basis

N = 32


def test_the_waveforms_are_the_unit_1x_cosine_and_sine_in_the_haar_layout():
    basis = sinusoid_control_basis(N)
    theta = 2 * np.pi * np.arange(N) / N
    haar = control_basis("haar", N, [1])
    assert basis.labels == haar.labels  # same layout: p1/q1/{even,odd}/c{axis}
    for row, label in zip(basis.weights, basis.labels, strict=True):
        axis = int(label[-1])
        wave = np.cos(theta) if "/even/" in label else np.sin(theta)
        np.testing.assert_allclose(row[axis], math.sqrt(2 / N) * wave, atol=1e-15)
        assert not np.delete(row, axis, axis=0).any()
    gram = np.einsum("iak,jak->ij", basis.weights, basis.weights)
    np.testing.assert_allclose(gram, np.eye(8), atol=1e-14)  # orthonormal, as the Haar one
    odd_only = sinusoid_control_basis(N, quadratures=("odd",))
    assert odd_only.labels == tuple(f"p1/q1/odd/c{a}" for a in range(4))


def test_the_configuration_selects_it_for_the_1x_level_only():
    cfg = ControllerConfig(samples_per_rev=N, output_basis="sinusoid")
    assert selected_control_basis(cfg).labels == sinusoid_control_basis(N).labels
    assert control_waveform(cfg) == "sinusoid"
    assert control_waveform(ControllerConfig(samples_per_rev=N)) == "haar"
    with pytest.raises(ConfigError, match="output_basis"):
        ControllerConfig(samples_per_rev=N, output_basis="sinusoid", levels=(1, 2))
    with pytest.raises(ConfigError, match="output_basis"):
        ControllerConfig(output_basis="square")


SCENARIOS = Path(__file__).resolve().parents[2] / "config/scenarios"


def test_the_sinusoidal_force_leaves_no_odd_harmonics_at_the_second_critical_speed():
    """The Haar force's 3 x, 5 x, 7 x stay in the displacement; the sinusoid's do not."""
    from dataclasses import replace

    from amb_apps.closed_loop import fe_model, run_closed_loop
    from amb_apps.compare_runs import harmonic_content, run_metrics
    from amb_common.rig import load_rig
    from amb_plant_sim.scenario import load_scenario

    rig = load_rig()
    scenario = load_scenario(SCENARIOS / "mass_loss_second_critical.yaml", rig)
    scenario = replace(scenario, duration=max(e.time for e in scenario.events) + 2.5)
    omega = 2 * math.pi * scenario.speed_hz
    runs = {}
    for basis in ("wavelet", "sinusoid", "none"):
        controller, output = ("none", "wavelet") if basis == "none" else ("transient", basis)
        cfg = ControllerConfig(
            samples_per_rev=N, delay_periods=1, output_basis=output, controller=controller
        )
        model = None if basis == "none" else fe_model(rig, omega, cfg)
        runs[basis] = run_closed_loop(rig, scenario, cfg, model)
    force = np.array([c.force for c in runs["sinusoid"].commands])  # (periods, 4, N)
    spectrum = np.abs(np.fft.rfft(force, axis=2))
    assert spectrum[:, :, 1].max() * 2 / N > 50.0  # a 1 x force of more than 50 N acts
    assert spectrum[:, :, [0, *range(2, N // 2 + 1)]].max() < 1e-9 * spectrum[:, :, 1].max()
    h = {b: harmonic_content(r, revs=10)["harmonics_um"] for b, r in runs.items()}
    for k in ("3x", "5x", "7x"):
        assert h["sinusoid"][k] < 0.2 * h["wavelet"][k], (k, h)
        # PID only's level (probe noise and the rig's own harmonics, 0.1-0.2 um), give or take
        assert h["sinusoid"][k] < 1.2 * h["none"][k] + 0.05, (k, h)
    pid = run_metrics(runs["none"], scenario.speed_hz)
    sin = run_metrics(runs["sinusoid"], scenario.speed_hz)
    assert sin["steady_1x"] < 0.02 * pid["steady_1x"]
