"""
Steady-state prediction of section 7.4.1 (200 N step synchronous force at 22 Hz, PID only).

References: PyWavelets' periodised Haar DWT of one period (coefficient stream), the measured
run's own final 1 x coefficients (the predictor's final value, eq. 7.4-7.5), and the thesis's
statements on figures 7.2-7.13. The inverted model is that of all 8 sensors (section 6.4's
"full inverse dynamic model"); the inner-sensor alternative is tested for comparison.
"""

import numpy as np
import pytest
import pywt

from amb_apps.closed_loop import run_closed_loop
from amb_apps.prediction_cli import (
    DEFAULT_INVERSE_SENSORS,
    INVERSE_SENSORS,
    WAVELETS,
    coefficient_stream,
    predict_run,
    settling_period,
    wrapped_weights,
)
from amb_common.paths import config_file
from amb_common.rig import load_rig
from amb_controller.config import ControllerConfig
from amb_plant_sim.scenario import load_scenario

SPR = 64


def test_coefficient_stream_equals_pywt_haar_of_each_period():
    rng = np.random.default_rng(3)
    x = rng.standard_normal((4 * SPR, 8)) * 1e-5
    cfg = ControllerConfig(levels=(1, 2, 3), sensors=tuple(range(8)))
    q, labels = coefficient_stream(x, cfg)
    for k in range(4):
        ref = pywt.wavedec(x[k * SPR : (k + 1) * SPR, 3], "haar", level=6)
        # ref[1] = d6 (p = 1), ref[2] = d5 (p = 2), ref[3] = d4 (p = 3); even quadrature
        for p in (1, 2, 3):
            got = [q[k, labels.index(f"p{p}/q{j}/even/c3")] for j in range(1, 2 ** (p - 1) + 1)]
            assert np.allclose(np.abs(got), np.abs(ref[p]), rtol=1e-9, atol=1e-18)


@pytest.mark.parametrize("wavelet", ["haar", "db2", "db4"])
def test_wrapped_weights_give_the_steady_coefficients_of_a_periodic_signal(wavelet):
    n = np.arange(12 * SPR)
    x = np.zeros((n.size, 8))
    x[:, 0] = 1e-4 * np.cos(2 * np.pi * n / SPR + 0.3) + 3e-5 * np.sin(4 * np.pi * n / SPR)
    cfg = ControllerConfig(wavelet=wavelet, levels=(1, 2, 3), sensors=tuple(range(8)))
    q, labels = coefficient_stream(x, cfg)
    rows = [i for i, lab in enumerate(labels) if lab.endswith("/c0")]
    expected = wrapped_weights(wavelet, SPR, (1, 2, 3), 0) @ x[:SPR, 0]
    assert np.allclose(q[-1, rows], expected, rtol=1e-9, atol=1e-15)


def test_settling_period_of_a_known_sequence():
    seq = np.array([0, 0, 2.0, 1.5, 1.2, 1.04, 0.98, 1.0, 1.0, 1.0] + [1.0] * 10)
    assert settling_period(seq, 2) == 5  # |1.04 - 1| <= 0.05 from index 5 on


@pytest.fixture(scope="module")
def measured_run():
    """The 22 Hz step synchronous force run, PID only, once for the module."""
    rig = load_rig()
    scenario = load_scenario(config_file("scenarios/sync_force_200N_22Hz.yaml"), rig)
    step = next(e.time for e in scenario.events if e.kind == "sync_force")
    result = run_closed_loop(
        rig, scenario, ControllerConfig(samples_per_rev=SPR, controller="none")
    )
    return rig, result, scenario.speed_hz, step


@pytest.fixture(scope="module")
def predict(measured_run):
    """``predict(wavelet, inverse_sensors=default)``: prediction of the measured run (cached)."""
    cache = {}

    def get(wavelet: str, inverse_sensors: str = DEFAULT_INVERSE_SENSORS):
        key = (wavelet, inverse_sensors)
        if key not in cache:
            cache[key] = predict_run(*measured_run, wavelet, inverse_sensors)
        return cache[key]

    return get


def _phasor(pr, series, c):
    e = pr.labels.index(f"p1/q1/even/c{c}")
    o = pr.labels.index(f"p1/q1/odd/c{c}")
    return series[:, e] + 1j * series[:, o]


def test_default_inverse_is_the_full_model_of_all_sensors():
    # Section 6.4: "measuring the response at all the sensor locations allows a full model
    # of the system to be constructed, from which a full inverse dynamic model can be evaluated".
    assert INVERSE_SENSORS[DEFAULT_INVERSE_SENSORS] == tuple(range(8))


@pytest.mark.parametrize(
    "wavelet",
    [
        "haar",
        "db2",
        pytest.param(
            "db4",
            marks=pytest.mark.xfail(
                strict=True,
                reason="db4's level-1 analysis window spans 458 samples = 7.2 periods: its "
                "measured 1 x coefficient settles 4-5 periods after the signal (x1: 8 vs 4, "
                "x3: 15 vs 11 periods; haar 0-2, db2 1-2), and the prediction, built on it, "
                "at 0.545 s, as the measurement (haar 0.364 s, db2 0.455 s)",
            ),
        ),
    ],
)
def test_predicted_steady_state_settles_before_the_measured_response(predict, wavelet):
    # Section 7.4.1, figures 7.3-7.5 (Haar), 7.7-7.9 (db2), 7.11-7.13 (db4): "The predictive
    # steady state wavelet coefficients are seen to have a much shorter transient response
    # reaching steady state before the system". Worst x sensor; measured: 0.545 s (x3).
    s = predict(wavelet).summary
    assert s["predicted_settling_s"] < s["measured_settling_s"]


@pytest.mark.parametrize("wavelet", WAVELETS)
@pytest.mark.parametrize(
    "sensor",
    [
        "x1",
        "x2",
        pytest.param(
            "x3",
            marks=pytest.mark.xfail(
                strict=True,
                reason="x3 is near a node (8.1 um final 1 x against 411 um at x1): the "
                "least-squares inverse of the 8-sensor model leaves the synchronous force's "
                "residual outside the range of G(1); predicted/measured 2.31 (haar), 0.87 "
                "(db2), 0.79 (db4), 10.6 um at most",
            ),
        ),
        "x4",
    ],
)
def test_predicted_final_amplitude_matches_the_measured_one(predict, wavelet, sensor):
    # Section 7.4.1 (figure 7.2): the prediction "matches the steady state amplitude of the
    # measured response"; measured ratios 0.92-1.0 at x1, x2, x4.
    ratio = predict(wavelet).summary["sensors"][sensor]["amplitude_ratio"]
    assert abs(ratio - 1.0) <= 0.1


@pytest.mark.parametrize("wavelet", WAVELETS)
def test_predicted_1x_coefficient_has_a_reduced_transient_at_the_inner_sensors(predict, wavelet):
    # Section 7.4.1: "The predictive steady state response of the system has a greatly reduced
    # transient response"; measured peak |W| / peak |Q| at x2, x3: haar 0.36, 0.18; db2
    # 0.37, 0.06; db4 0.42, 0.10 (the measured 1 x overshoots its final value 2.4-11 x).
    pr = predict(wavelet)
    k0 = pr.step_period
    for c in (2, 4):  # x2, x3
        meas = _phasor(pr, pr.coefficients, c)[k0:]
        pred = _phasor(pr, pr.predicted_coefficients, c)[k0:]
        final = abs(meas[-10:].mean())
        assert np.abs(meas).max() > 2.0 * final  # the measured 1x overshoots strongly
        assert np.nanmax(np.abs(pred)) <= 0.5 * np.abs(meas).max()


def test_level_two_prediction_stays_below_the_measured_transient_at_the_inner_sensors(predict):
    # With the full-rank least-squares inverse of the rank-deficient level-2 model the 2 x
    # prediction peaked at 22-36 x the measured peak (inner-sensor model); truncated-SVD
    # inverse of the 8-sensor model: 0.24-0.56 (haar, x2, y2, x3, y3).
    pr = predict("haar")
    k0 = pr.step_period
    for c in (2, 3, 4, 5):
        cols = [i for i, lab in enumerate(pr.labels) if lab.startswith("p2/") and
                lab.endswith(f"/c{c}")]  # fmt: skip
        meas = np.nanmax(np.abs(pr.coefficients[k0:, cols]))
        pred = np.nanmax(np.abs(pr.predicted_coefficients[k0:, cols]))
        assert pred <= 0.6 * meas


def test_inner_sensor_inverse_is_exact_in_the_steady_state_but_settles_after_the_measurement(
    predict,
):
    # The alternative B^(m) (planes 2, 3 only, a square model): exact steady state where it
    # measures (x2, x3 within 3 %; x3 was 2.31 x with all sensors), but it settles one period
    # after the measurement (haar 0.591 s vs 0.545 s), against the thesis's figures 7.3-7.5:
    # no 5th-order inverse equalises the 1 x model (||B * G - I|| / ||I|| >= 0.53).
    pr = predict("haar", "inner")
    for c in (2, 4):  # x2, x3
        meas = _phasor(pr, pr.coefficients, c)[-10:].mean()
        pred = _phasor(pr, pr.predicted_coefficients, c)[-10:].mean()
        assert abs(pred - meas) <= 0.03 * abs(meas)
    s = pr.summary
    assert s["predicted_settling_s"] > s["measured_settling_s"]
