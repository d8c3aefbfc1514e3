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
        pytest.param(
            "db2",
            marks=pytest.mark.xfail(
                strict=True,
                reason="db2's level-1 analysis window spans 206 samples = 3.2 periods: the "
                "prediction settles 10 periods after the step at x3, x4 (0.455 s), in the "
                "same period as the measured x3 (0.455 s); it led by two periods only while "
                "the measured x3 took 12 (0.545 s, rig model before #16)",
            ),
        ),
        pytest.param(
            "db4",
            marks=pytest.mark.xfail(
                strict=True,
                reason="db4's level-1 analysis window spans 458 samples = 7.2 periods: its "
                "measured 1 x coefficient settles 3-4 periods after the signal (x1: 8 vs 5, "
                "x3: 14 vs 10 periods; haar 0, db2 1), and the prediction, built on it, at "
                "0.591 s, after the measurement (0.455 s; haar 0.364 s, db2 0.455 s)",
            ),
        ),
    ],
)
def test_predicted_steady_state_settles_before_the_measured_response(predict, wavelet):
    # Section 7.4.1, figures 7.3-7.5 (Haar), 7.7-7.9 (db2), 7.11-7.13 (db4): "The predictive
    # steady state wavelet coefficients are seen to have a much shorter transient response
    # reaching steady state before the system". Worst x sensor, i.e. the whole x response:
    # measured 0.455 s, set by x3, near a node of the steady 1 x (9 um against 445 um at x1).
    # The lead is there only: the prediction's settling is set by its own analysis window and
    # 5-period inverse (haar 6-8 periods at x1-x4 on either rig model), and away from x3 the
    # measured response settles sooner (5-7 periods; docs/controller_notes.md).
    s = predict(wavelet).summary
    assert s["predicted_settling_s"] < s["measured_settling_s"]


_NODE = pytest.mark.xfail(
    strict=True,
    reason="x3 is near a node (9.3 um final 1 x against 445 um at x1): the least-squares "
    "inverse of the 8-sensor model leaves the synchronous force's residual outside the range "
    "of G(1); predicted/measured 3.87 (haar), 2.47 (db2), 1.32 (db4), 27 um at most",
)
_HAAR_4X = pytest.mark.xfail(
    strict=True,
    reason="Haar's 4 x level carries 14 % of a 1 x (levels 1-3 rebuild sinc^2(pi/8) = 0.95 of "
    "it, levels 1-2 0.81), and the 4 x coefficients of the synchronous response lie 46 % "
    "outside the range of the 8-sensor level-3 model: predicted/measured 0.87 (x2), 1.11 "
    "(x4), 0.93, 0.98 on the rig model before #16; 0.93, 0.93 with the measured 4 x level "
    "(test_haar_1x_and_2x_levels_predict_the_measured_amplitude)",
)


def _amplitude_case(sensor: str, wavelet: str):
    marks = ()
    if sensor == "x3":
        marks = _NODE
    elif wavelet == "haar" and sensor in ("x2", "x4"):
        marks = _HAAR_4X
    return pytest.param(sensor, wavelet, marks=marks, id=f"{sensor}-{wavelet}")


@pytest.mark.parametrize(
    ("sensor", "wavelet"),
    [_amplitude_case(s, w) for s in ("x1", "x2", "x3", "x4") for w in WAVELETS],
)
def test_predicted_final_amplitude_matches_the_measured_one(predict, wavelet, sensor):
    # Section 7.4.1 (figure 7.2): the prediction "matches the steady state amplitude of the
    # measured response", read as within 10 % (config/reproduce.yaml). Measured ratios at x1,
    # x2, x4: db2 0.95-1.06, db4 0.99-1.00, haar 0.92 at x1 (x2, x4: _HAAR_4X).
    ratio = predict(wavelet).summary["sensors"][sensor]["amplitude_ratio"]
    assert abs(ratio - 1.0) <= 0.1


def test_haar_1x_and_2x_levels_predict_the_measured_amplitude(predict):
    # Where the Haar prediction misses the 10 % at x2, x4 (_HAAR_4X): with the measured 4 x
    # level in place of the predicted one, the rebuilt final 1 x is within the same 10 % of the
    # measured at x1, x2, x4 (0.95, 0.93, 0.93; the levels-1-3 rebuild alone keeps
    # sinc^2(pi/8) = 0.95 of a 1 x), so the 1 x and 2 x predictions match the steady state and
    # the error is the 4 x level's. Reference: the measured signal's 1 x Fourier component.
    pr = predict("haar")
    q = pr.coefficients[-10:].mean(axis=0)
    w = pr.predicted_coefficients[-10:].mean(axis=0)
    level3 = np.array([lab.startswith("p3/") for lab in pr.labels])
    steady = np.where(level3, q, w)  # predicted 1 x and 2 x levels, measured 4 x level
    for c in (0, 2, 6):  # x1, x2, x4
        rows = [i for i, lab in enumerate(pr.labels) if lab.endswith(f"/c{c}")]
        period = np.linalg.pinv(wrapped_weights("haar", SPR, (1, 2, 3), c)) @ steady[rows]
        rebuilt = abs(np.fft.rfft(period)[1])
        measured = abs(np.fft.rfft(pr.measured[-10 * SPR :, c].reshape(10, SPR))[:, 1].mean())
        assert abs(rebuilt / measured - 1.0) <= 0.1


@pytest.mark.parametrize("wavelet", WAVELETS)
def test_predicted_1x_coefficient_has_a_reduced_transient_where_the_measured_one_overshoots(
    predict, wavelet
):
    # Section 7.4.1: "The predictive steady state response of the system has a greatly reduced
    # transient response". Where the measured 1 x coefficient overshoots its final value more
    # than 2 x, a prediction that stepped to that final value would peak below half the
    # measured peak: the bound is that half. Which sensors overshoot depends on the rig model
    # (x3, y3 11-21 x, x4, y4 2.8-5.2 x; x2, y2, where the steady 1 x tripled, 1.2-1.6 x); peak
    # |W| / peak |Q| there: haar 0.12-0.34, db2 0.12-0.34, db4 0.07-0.40.
    pr = predict(wavelet)
    k0 = pr.step_period
    overshooting = 0
    for c in range(8):
        meas = _phasor(pr, pr.coefficients, c)[k0:]
        if np.abs(meas).max() <= 2.0 * abs(meas[-10:].mean()):
            continue
        overshooting += 1
        pred = _phasor(pr, pr.predicted_coefficients, c)[k0:]
        assert np.nanmax(np.abs(pred)) <= 0.5 * np.abs(meas).max()
    assert overshooting >= 2  # a transient to reduce, in x and y at least


def test_level_two_prediction_stays_below_the_measured_transient_at_the_inner_sensors(predict):
    # With the full-rank least-squares inverse of the rank-deficient level-2 model the 2 x
    # prediction peaked at 22-36 x the measured peak (inner-sensor model). A steady-state
    # prediction peaks near the measured final value, which the measured series reaches from
    # below or overshoots: the bound is the measured peak. Truncated-SVD inverse of the
    # 8-sensor model (haar; x2, y2, x3, y3): 0.79, 0.78, 0.49, 0.14; the measured 2 x
    # coefficients at x2, y2 overshoot their final value 1.27-1.29 x only (rig model before
    # #16: 2.7-2.8 x, ratios 0.24-0.56), so an exact prediction would score 0.77-0.79 there.
    pr = predict("haar")
    k0 = pr.step_period
    for c in (2, 3, 4, 5):
        cols = [i for i, lab in enumerate(pr.labels) if lab.startswith("p2/") and
                lab.endswith(f"/c{c}")]  # fmt: skip
        meas = np.nanmax(np.abs(pr.coefficients[k0:, cols]))
        pred = np.nanmax(np.abs(pr.predicted_coefficients[k0:, cols]))
        assert pred <= meas


def test_inner_sensor_inverse_is_exact_in_the_steady_state_but_does_not_settle_first(predict):
    # The alternative B^(m) (planes 2, 3 only, a square model): exact steady state where it
    # measures (x2, x3 within 3 %: 0.03 %, 0.2 %; x3 is 3.9 x with all sensors), but it does
    # not reach the steady state before the measurement, against the thesis's figures 7.3-7.5:
    # no 5th-order inverse equalises the 1 x model (||B * G - I|| / ||I|| >= 0.58). Haar,
    # periods after the step, predicted / measured: x1 7 / 5, x2 7 / 6, x3 10 / 10, x4 9 / 7
    # (whole x response 0.455 s both; before #16 the prediction settled a period after it,
    # 0.591 s against 0.545 s).
    pr = predict("haar", "inner")
    for c in (2, 4):  # x2, x3
        meas = _phasor(pr, pr.coefficients, c)[-10:].mean()
        pred = _phasor(pr, pr.predicted_coefficients, c)[-10:].mean()
        assert abs(pred - meas) <= 0.03 * abs(meas)
    s = pr.summary
    assert s["predicted_settling_s"] >= s["measured_settling_s"]
