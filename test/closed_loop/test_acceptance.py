"""
Thesis section 8.5.3 on the FE plant: 430 g cm mass loss at D1 at the first two critical speeds.

PID only against PID + wavelet transient controller (Haar, x_{1,1}, w = v = 0.75, delay 2,
5th-order inverse of the chapter-6 FE-route model, inner sensors measured). Acceptance
(issue text): steady 1 x at the inner sensors reduced by >= 90 %, peak transient no larger,
settling within 10 revolutions.

What the design prescribes (eq. 8.3-8.11, sign convention of :mod:`amb_controller.stability`)
----------------------------------------------------------------------------------------------
With an exact inverse, ``G B_u (G B_u)^* = I``, the loop ``I + G B_u L`` maps the PID-only
response ``Q_u`` of any disturbance to the controlled ``Q_c = T(z) Q_u``:

* no delay (eq. 8.5, 8.9): ``T = alpha(z)(z - 1)``; for a step in the disturbance
  coefficient ``Q_c = alpha G B_u`` (eq. 8.3) and ``alpha = w / (z - v)`` leaves the fraction
  ``c_k = w v^(k-1)`` (eq. 8.7) after k periods, ``0.75^k`` for ``w = v = 0.75``: the
  remaining error, not a cumulative sum; it first falls below 5 % at k = 11. The mass loss
  is not a step in ``Q_u`` (the PID loop takes ~3 periods to respond), so ``alpha(z)(z - 1)
  Q_u`` settles later: 14 periods at 11 Hz, 15 at 18 Hz.
* delay i (eq. 8.10-8.11): the delay is not inside ``alpha``:
  ``T = alpha (z - 1) z^i / (1 + alpha (z - 1)(z^i - 1))``, for w = v = 0.75, i = 2,
  ``z (z - 1) / (z^2 - z + 1/3)`` (poles ``|z| = 1 / sqrt(3)``): 7 periods.

The 1 x model ``G(z)`` has transmission zeros outside the unit circle (``|z|`` 1.21 at 11 Hz,
1.23 at 18 Hz): no causal inverse makes ``G B_u (G B_u)^* = I``, and the least-squares
inverse of eq. 6.35 leaves ``||B * A - I||`` 0.51 / 0.48 at k = 0 (5th order; 0.48 / 0.45 at
20th order). The wavelet-domain loop of eq. 8.10 with that inverse, which the FE run
reproduces, settles in 10 periods at 11 Hz (5th or 10th order): within the thesis's 10
revolutions, three periods after the exact inverse's 7. At 18 Hz it takes 19 periods with the
5th-order inverse and 11 with the 10th. The 8-sensor least-squares inverse is no way out: its
integral action can only drive ``B(1) q``, not ``q``, to zero (11 Hz FE run: 96 um 1 x over
the last 10 revolutions at the inner sensors against 133 um with PID alone, 756 um peak, one
contact).
(The rig model of ``config/rig.yaml``; ``docs/history.md`` has the same figures on earlier
models.)
"""

import functools
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy import signal

from amb_apps.closed_loop import fe_model, run_closed_loop
from amb_common.rig import load_rig
from amb_controller.config import ControllerConfig
from amb_controller.inverse import pseudo_inverse_series, series_product
from amb_controller.metrics import INNER, compute_metrics, inner_summary, settling_periods
from amb_plant_sim.scenario import load_scenario

SCENARIOS = Path(__file__).resolve().parents[2] / "config/scenarios"
SPEEDS = {"11Hz": "mass_loss_first_critical.yaml", "18Hz": "mass_loss_second_critical.yaml"}
W = V = 0.75
DELAY = 2


@functools.cache
def _scenario(speed: str):
    rig = load_rig()
    return rig, load_scenario(SCENARIOS / SPEEDS[speed], rig)


@functools.cache
def runs(speed: str, inverse_order: int = 5) -> dict:
    """PID-only and transient runs of one speed (cached for the module)."""
    rig, scenario = _scenario(speed)
    cfg = ControllerConfig(
        samples_per_rev=64, w=W, v=V, delay_periods=DELAY, inverse_order=inverse_order
    )
    model = fe_model(rig, 2 * math.pi * scenario.speed_hz, cfg)
    out = {"model": model, "fault_period": None}
    for name in ("none", "transient"):
        result = run_closed_loop(rig, scenario, replace(cfg, controller=name), model)
        metrics = compute_metrics(result, scenario.speed_hz)
        out[name] = inner_summary(metrics)
        out[f"{name}_phasor"] = result.phasor
        out["fault_period"] = metrics["fault_period"]
    return out


def _change_after_fault(phasor: np.ndarray, fault_period: int) -> np.ndarray:
    """PID-only 1 x change from the last period before the fault (zero before it)."""
    du = phasor - phasor[fault_period - 1]
    du[:fault_period] = 0.0
    return du


def _settling(series: np.ndarray, fault_period: int) -> int:
    return int(settling_periods(series[:, INNER], fault_period).max())


@pytest.mark.parametrize("speed", SPEEDS)
def test_steady_sync_vibration_at_inner_sensors_reduced_by_90_percent(speed):
    pid, wav = runs(speed)["none"], runs(speed)["transient"]
    assert pid["steady_1x"] > 50e-6  # the mass loss at a critical speed is large
    assert wav["steady_1x"] <= 0.1 * pid["steady_1x"]


@pytest.mark.parametrize("speed", SPEEDS)
def test_peak_transient_no_larger_than_pid_only(speed):
    assert runs(speed)["transient"]["peak"] <= runs(speed)["none"]["peak"]


@pytest.mark.parametrize("speed", SPEEDS)
def test_fe_loop_realises_eq_8_10_with_the_model_inverse(speed):
    # Reference: the wavelet-domain loop written out here, q[k] = q_u[k] + sum_j A^(j) u[k-j],
    # u[k+i] = -z^-i B(z) beta(z) q with beta = 1/(alpha (z-1)) - 1 = ((1-w)/w) / (1 - z^-1)
    # for w = v (eq. 8.6, 8.10): an integrator of the inverse's output. The FE run (plant,
    # filterbank, pipeline, synthesis) must follow it: the slow settling is the design's.
    r = runs(speed)
    markov, inverse = r["model"].markov, r["model"].inverse
    inner = np.asarray(INNER)
    pid = r["none_phasor"][:, inner]
    q_u = np.concatenate([pid.real, pid.imag], axis=1)  # the model's (quadrature, sensor) order
    n_periods, n_u = q_u.shape[0], markov.shape[2]
    q = np.zeros_like(q_u)
    u = np.zeros((n_periods + DELAY, n_u))
    integral = np.zeros(n_u)
    for k in range(n_periods):
        j = np.arange(min(k + 1, markov.shape[0]))
        q[k] = q_u[k] + np.einsum("jyu,ju->y", markov[j], u[k - j])
        m = np.arange(min(k + 1, inverse.shape[0]))
        integral += np.einsum("muy,my->u", inverse[m], q[k - m])
        u[k + DELAY] = -(1.0 - W) / W * integral
    nominal = q[:, :4] + 1j * q[:, 4:]
    measured = r["transient_phasor"][:, inner]
    k_f = r["fault_period"]
    scale = np.abs(measured[k_f:] - measured[-10:].mean(axis=0)).max(axis=0)
    deviation = np.abs((measured - nominal)[k_f : k_f + 25]) / scale
    assert deviation.max() <= 0.05
    full = np.zeros((n_periods, 8), complex)
    full[:, inner] = nominal
    assert abs(_settling(full, k_f) - r["transient"]["settling"]) <= 1


@pytest.mark.parametrize("speed", SPEEDS)
def test_no_causal_inverse_equalises_the_1x_model(speed):
    # Zeros of det G(z), G = sum_k A^(k) z^-k (25 terms), from the block companion matrix of
    # z^24 G(z) (A^(0) invertible): some lie outside the unit circle, so G B_u (G B_u)^* = I
    # has no stable causal solution and the least-squares inverse keeps a residual at k = 0.
    rig, scenario = _scenario(speed)
    cfg = ControllerConfig(samples_per_rev=64)
    markov = fe_model(rig, 2 * math.pi * scenario.speed_hz, cfg, n_terms=25).markov
    n, m = markov.shape[1], markov.shape[0] - 1
    companion = np.zeros((n * m, n * m))
    companion[:n] = -np.linalg.solve(markov[0], np.hstack(list(markov[1:])))
    companion[n:, :-n] = np.eye(n * (m - 1))
    assert np.abs(np.linalg.eigvals(companion)).max() > 1.1  # clearly outside: 1.21 / 1.23
    for order in (5, 20):
        product = series_product(pseudo_inverse_series(markov, order), markov)
        assert np.linalg.norm(product[0] - np.eye(n), 2) > 0.4


def test_prescribed_response_needs_more_than_10_revolutions():
    # eq. 8.6-8.7: c_k = w v^(k-1) first falls below 5 % at k = 11 > 10.
    k = np.arange(1, 30)
    c = W * V ** (k - 1)
    assert int(k[np.argmax(c < 0.05)]) == 11 == math.ceil(math.log(0.05) / math.log(V))
    # eq. 8.3 / 8.9 on the mass loss itself: Q_c = alpha(z)(z - 1) Q_u, i.e.
    # w (1 - z^-1) / (1 - v z^-1) applied to the PID-only 1 x change.
    r = runs("11Hz")
    k_f = r["fault_period"]
    designed = signal.lfilter([W, -W], [1.0, -V], _change_after_fault(r["none_phasor"], k_f), 0)
    # 14 periods with the loss at 2.0 s, 15 with it at 4.0 s (late in its control period: the
    # period of the fault carries less of the change): more than 10 wherever it falls
    assert 14 <= _settling(designed, k_f) <= 15


@pytest.mark.parametrize("speed", SPEEDS)
def test_exact_inverse_with_the_delay_would_settle_within_10_revolutions(speed):
    # eq. 8.11, w = v = 0.75, i = 2, exact inverse: Q_c = z (z - 1) / (z^2 - z + 1/3) Q_u.
    r = runs(speed)
    k_f = r["fault_period"]
    du = _change_after_fault(r["none_phasor"], k_f)
    designed = signal.lfilter([1.0, -1.0], [1.0, -1.0, 1.0 / 3.0], du, axis=0)
    assert np.allclose(np.abs(np.roots([1.0, -1.0, 1.0 / 3.0])), 1 / math.sqrt(3))
    assert _settling(designed, k_f) <= 8
    # the least-squares inverse's residual costs periods: the loop settles later (3 at 11 Hz)
    assert r["transient"]["settling"] > _settling(designed, k_f)


@pytest.mark.parametrize(
    ("speed", "inverse_order"),
    [
        ("11Hz", 5),
        pytest.param(
            "18Hz",
            5,
            marks=pytest.mark.xfail(
                strict=True,
                reason="18 Hz, 5th-order inverse (the thesis's choice, section 8.5.1): the "
                "truncated inverse slows the loop to 19 periods against 15 of "
                "alpha(z)(z-1) Q_u (10th order: 11)",
            ),
        ),
        ("18Hz", 10),
    ],
)
def test_settles_no_later_than_the_prescribed_response_to_the_same_disturbance(
    speed, inverse_order
):
    r = runs(speed, inverse_order)
    k_f = r["fault_period"]
    designed = signal.lfilter([W, -W], [1.0, -V], _change_after_fault(r["none_phasor"], k_f), 0)
    assert r["transient"]["settling"] <= _settling(designed, k_f)


@pytest.mark.parametrize(
    "speed",
    [
        "11Hz",
        pytest.param(
            "18Hz",
            marks=pytest.mark.xfail(
                strict=True,
                reason="the 5th-order inverse (section 8.5.1) leaves a residual that slows the "
                "loop to 19 periods at 18 Hz (11 with the 10th order); the exact inverse would "
                "settle in 8 (eq. 8.11), the prescribed alpha(z)(z-1) Q_u in 15 (eq. 8.3, 8.9)",
            ),
        ),
    ],
)
def test_settling_within_10_revolutions(speed):
    assert runs(speed)["transient"]["settling"] <= 10


def test_pid_only_run_sends_zero_commands_every_period():
    rig, scenario = _scenario("11Hz")
    scenario = replace(scenario, duration=0.5)
    cfg = ControllerConfig(samples_per_rev=32, controller="none")
    result = run_closed_loop(rig, scenario, cfg)
    n_periods = round(0.5 * scenario.speed_hz)
    assert [c.target_period for c in result.commands] == [k + DELAY for k in range(n_periods)]
    assert np.all(result.wavelet_force == 0)
