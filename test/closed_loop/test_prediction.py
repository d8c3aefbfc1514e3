"""
Steady-state prediction of section 7.4.1 (200 N step synchronous force at 22 Hz, PID only).

References: PyWavelets' periodised Haar DWT of one period (coefficient stream), the measured
run's own final 1 x coefficients (the predictor's final value, eq. 7.4-7.5).
"""

import numpy as np
import pytest
import pywt

from amb_controller.pipeline import ControllerConfig
from amb_controller.prediction_cli import (
    coefficient_stream,
    run_prediction,
    settling_period,
    wrapped_weights,
)

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
def haar():
    results, _ = run_prediction(("haar",))
    return results["haar"]


def _phasor(pr, series, c):
    e = pr.labels.index(f"p1/q1/even/c{c}")
    o = pr.labels.index(f"p1/q1/odd/c{c}")
    return series[:, e] + 1j * series[:, o]


def test_predicted_1x_coefficient_reaches_the_measured_final_value_at_the_inner_sensors(haar):
    for c in (2, 4):  # x2, x3 (inverted sensors)
        meas = _phasor(haar, haar.coefficients, c)[-10:].mean()
        pred = _phasor(haar, haar.predicted_coefficients, c)[-10:].mean()
        assert abs(pred - meas) <= 0.03 * abs(meas)


def test_predicted_1x_coefficient_has_a_reduced_transient_at_the_inner_sensors(haar):
    # thesis 7.4.1: "greatly reduced transient response"; measured here: peak |W| / peak |Q|
    # = 0.38 (x2) and 0.36 (x3); the overshoot over the final value stays (x3: 2.8 x)
    k0 = haar.step_period
    for c in (2, 4):  # x2, x3: the sensors the inverse is built from
        meas = _phasor(haar, haar.coefficients, c)[k0:]
        pred = _phasor(haar, haar.predicted_coefficients, c)[k0:]
        final = abs(meas[-10:].mean())
        assert np.abs(meas).max() > 2.0 * final  # the measured 1x overshoots strongly
        assert np.abs(pred).max() <= 0.5 * np.abs(meas).max()


def test_level_two_prediction_stays_below_the_measured_transient_at_the_inner_sensors(haar):
    # With the full-rank least-squares inverse of the rank-deficient level-2 model the 2 x
    # prediction peaked at 22-36 x the measured peak (x2, y2, x3, y3); truncated-SVD inverse:
    # 0.32-0.47 (measured).
    k0 = haar.step_period
    for c in (2, 3, 4, 5):
        cols = [i for i, lab in enumerate(haar.labels) if lab.startswith("p2/") and
                lab.endswith(f"/c{c}")]  # fmt: skip
        meas = np.nanmax(np.abs(haar.coefficients[k0:, cols]))
        pred = np.nanmax(np.abs(haar.predicted_coefficients[k0:, cols]))
        assert pred <= 0.6 * meas


@pytest.mark.xfail(
    strict=True,
    reason="thesis figs 7.2-7.5: prediction settles first; with the inner-sensor inverse it "
    "settles 1 period after the measurement (haar 0.591 s vs 0.545 s; db2 0.591, db4 0.636): "
    "no 5th-order inverse equalises the 1 x model, ||B*G - I|| / ||I|| = 0.53 at best and "
    "2.44 with the B(1) G(1) = I weight 10 (haar; db2 1.00/1.56, db4 1.00/2.58), and the "
    "outer sensors x1, x4 (worst) are predicted through G_all(1) from an "
    "equivalent control step that a sinusoidal force is not (final 1 x ratio 0.63-0.78); "
    "the all-sensor inverse settles first (test_full_model_inverse_...)",
)
def test_predicted_steady_state_settles_before_the_measured_response(haar):
    s = haar.summary
    assert s["predicted_settling_s"] < s["measured_settling_s"]


@pytest.fixture(scope="module")
def haar_all():
    results, _ = run_prediction(("haar",), inverse_sensors="all")
    return results["haar"]


def test_full_model_inverse_settles_before_the_measured_response(haar_all):
    # Section 6.4's "full inverse dynamic model" from all 8 sensors (least-squares left
    # inverse): the prediction enters the 5 % band first (measured: 0.364 s vs 0.545 s),
    # at the price of a biased final value at the near-node sensor x3 (level_operator doc).
    s = haar_all.summary
    assert s["predicted_settling_s"] < s["measured_settling_s"]
    for name in ("x1", "x2", "x4"):  # large-amplitude sensors: final 1 x within 10 %
        assert abs(s["sensors"][name]["amplitude_ratio"] - 1.0) <= 0.1
