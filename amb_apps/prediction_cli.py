"""
Steady-state prediction on a measured run (thesis section 7.4.1, figures 7.2-7.13).

A synchronous force of 200 N is stepped on through bearing 1 at 22 Hz
(``config/scenarios/sync_force_200N_22Hz.yaml``, PID only). The measured displacements are
streamed through the project's front end and causal filterbank exactly as the
``wavelet_filterbank`` node does, the coefficient vector of each control period is
assembled as the ``wavelet_controller`` node does (:class:`ControllerPipeline`, all 8
sensors, levels p = 1, 2, 3 = 1 x, 2 x, 4 x, both quadratures), and each level is passed
through its own steady-state predictor ``W = S Q`` with ``S = Gamma (G B_u)^*`` (eq. 7.2,
7.6; :func:`level_operator`), from the FE-route model of that level
(:func:`~amb_apps.closed_loop.fe_model`, 5th-order inverse as in section 7.4.2, with
the ``B(1) G(1) = I`` weight of :mod:`amb_controller.inverse`, truncated-SVD inverse of the
rank-deficient level models, ``RANK_RTOL``). The inverted model is that of all 8 sensors by
default, as in section 6.4 (:func:`level_operator`).
The thesis identified ``(G B_u)^*`` on line; here the model is the simulator's own FE
closed loop, so the comparison tests the method, not an identification.

Reconstruction (decision)
-------------------------
The thesis reconstructs "the predicted steady state signal" from the three levels with the
decomposition residue set to zero, but does not say how the causal coefficients are
placed in time. A steady state is periodic, and for an N-periodic signal the causal
filterbank coefficient of period k is the inner product of one period of the signal with
the analysis weights wrapped modulo N (:func:`wrapped_weights`). The predicted signal of
period k is the minimum-norm period whose wrapped-weight coefficients equal the predicted
``W_k`` (even and odd quadratures of levels 1-3): ``x_k = M^+ W_k``. Levels 4-6 and the
approximation carry no prediction (residue zero), as in the thesis.

Settling (decision)
-------------------
Per x sensor, the 1 x phasor of a period is the synchronous Fourier component of the
period, ``(2 / N) sum_n x[n] e^(-i 2 pi n / N)`` (m), of the measured displacement and of
the predicted steady-state signal. A series has settled at the end of the first period
after the step from which ``|X_k - X_final| <= 0.05 |X_final|`` for every later period,
``X_final`` the mean of the last 10 periods of that series (predicted and measured final
amplitudes are compared separately, ``amplitude_ratio``). Times are measured from the
step, at the end of the period (when the value exists).

Command: ``python -m amb_apps.prediction_cli --out DIR [--json] [--inverse-sensors
inner|all]`` writes
``prediction.json`` and, per wavelet, ``prediction_<wavelet>_signal.png`` (figure 7.2 style)
and ``prediction_<wavelet>_coefficients.png`` (figures 7.3-7.5 style).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from amb_apps.closed_loop import fe_model, run_closed_loop
from amb_common.paths import config_file
from amb_common.rig import load_rig
from amb_controller.basis import measurement_basis
from amb_controller.config import ControllerConfig
from amb_controller.inverse import dc_gain, pseudo_inverse_series, series_product
from amb_controller.pipeline import ControllerPipeline
from amb_plant_sim.scenario import load_scenario
from amb_wavelet.analysis import AnalysisFilterbank
from amb_wavelet.frontend import FRAMES, QUADRATURES, ChannelFrontEnd

__all__ = [
    "LEVELS",
    "WAVELETS",
    "PredictionResult",
    "apply_operator",
    "coefficient_stream",
    "level_operator",
    "main",
    "predict_run",
    "settling_period",
    "sync_phasors",
    "wrapped_weights",
]

LEVELS = (1, 2, 3)  # thesis p: 1 x, 2 x, 4 x (x_{1,1}, x_{2,1}, x_{3,1})
WAVELETS = ("haar", "db2", "db4")
X_SENSORS = (0, 2, 4, 6)  # x1, x2, x3, x4
BAND = 0.05
FINAL_PERIODS = 10
INVERSE_ORDER = 5  # section 7.4.2
DC_WEIGHT = 10.0
#: Sensors whose model is inverted (``B^(m)`` of eq. 7.2): all 8 (default, section 6.4) or the
#: inner planes 2, 3 beside the AMBs.
INVERSE_SENSORS = {"inner": (2, 3, 4, 5), "all": tuple(range(8))}
DEFAULT_INVERSE_SENSORS = "all"
#: Relative singular-value cutoff of ``G(1)`` for the inverse: the FE level models p >= 2 are
#: structurally rank deficient (singular values 1e-16 of the largest; :mod:`amb_controller.
#: inverse`), their genuine singular values are >= 3.9e-3 of the largest (db2, p = 2): any
#: cutoff between 1e-14 and 1e-3 selects the same rank. 1e-8 ~ sqrt(machine epsilon).
RANK_RTOL = 1e-8


class PredictionValueError(ValueError):
    """An argument of the prediction is out of range (the message says which)."""


def coefficient_stream(
    displacement: np.ndarray, config: ControllerConfig, capacity: float | None = None
) -> tuple[np.ndarray, tuple[str, ...]]:
    """
    Return the measured coefficient vector of every period, as the controller node sees it.

    Parameters
    ----------
    displacement : numpy.ndarray
        ``(n, 8)`` m, samples from sample index 0, speed-synchronous (angle
        ``2 pi n / samples_per_rev``, the simulator's keyphasor convention).
    config : ControllerConfig
        Wavelet, levels, quadratures and sensors of the vector.
    capacity : float, optional
        Bearing capacity per axis, N; default the rig's (``amb.force_limit`` of
        config/rig.yaml). The pipeline only measures here (controller ``none``).

    Returns
    -------
    tuple of (numpy.ndarray, tuple of str)
        ``(K, n_y)`` m sqrt(samples), NaN rows for periods the pipeline could not use
        (start-up of long wavelets), and the labels (``p1/q1/even/c0``...).

    """
    x = np.asarray(displacement, dtype=float)
    if x.ndim != 2 or x.shape[1] != 8:
        raise PredictionValueError(f"displacement must have shape (n, 8), got {x.shape}")
    spr = config.samples_per_rev
    cfg = replace(config, controller="none")
    front = ChannelFrontEnd(spr, FRAMES, QUADRATURES)
    bank = AnalysisFilterbank(cfg.wavelet, spr.bit_length(), front.n_channels)
    if capacity is None:
        capacity = load_rig().amb.force_limit
    pipeline = ControllerPipeline(cfg, capacity, None, channel_labels=front.labels)
    n_periods = x.shape[0] // spr
    out = np.full((n_periods, pipeline.measured.n_coefficients), np.nan)
    angle = 2 * np.pi * (np.arange(n_periods * spr) % spr) / spr
    for n in range(n_periods * spr):
        records = bank.step(front.step(x[n], angle[n]), n)
        if pipeline.on_sample(n, records, x[n]) is not None and pipeline.last_measured is not None:
            out[n // spr] = pipeline.last_measured
    return out, pipeline.measured.labels


def wrapped_weights(wavelet: str, samples_per_rev: int, levels, channel: int = 0) -> np.ndarray:
    """
    Return the analysis weights of one channel wrapped onto one period (modulo N).

    For an N-periodic signal ``x``, coefficient ``i`` of the causal filterbank is
    ``M[i] @ x[0:N]`` (module docstring).

    Parameters
    ----------
    wavelet : str
        PyWavelets name.
    samples_per_rev : int
        N.
    levels : sequence of int
        Thesis levels p.
    channel : int
        Sensor channel whose rows are returned.

    Returns
    -------
    numpy.ndarray
        ``(n_coefficients_of_channel, N)``, rows in the basis order (level, q, quadrature).

    """
    basis = measurement_basis(wavelet, samples_per_rev, levels)
    rows = [i for i, lab in enumerate(basis.labels) if lab.endswith(f"/c{channel}")]
    w = basis.weights[rows, channel, :]
    idx = (basis.offset + np.arange(w.shape[1])) % samples_per_rev
    out = np.zeros((len(rows), samples_per_rev))
    np.add.at(out.T, idx, w.T)
    return out


def sync_phasors(x: np.ndarray, samples_per_rev: int) -> np.ndarray:
    """
    Return the 1 x Fourier phasor of each whole period, ``(2/N) sum x e^(-i 2 pi n/N)`` (m).

    Parameters
    ----------
    x : numpy.ndarray
        ``(n, c)`` samples from a period start.
    samples_per_rev : int
        N.

    Returns
    -------
    numpy.ndarray of complex
        ``(K, c)``.

    """
    n = samples_per_rev
    k = x.shape[0] // n
    phase = np.exp(-2j * np.pi * np.arange(n) / n)
    return (
        2.0 / n * np.einsum("kn,knc->kc", phase[None, :].repeat(k, 0), x[: k * n].reshape(k, n, -1))
    )


def settling_period(phasor: np.ndarray, start: int, band: float = BAND) -> int | None:
    """
    Return the first period ``k >= start`` after which ``|X - X_final| <= band |X_final|``.

    Parameters
    ----------
    phasor : numpy.ndarray of complex
        ``(K,)`` per-period phasors (NaN allowed before ``start``).
    start : int
        Period of the step.
    band : float
        Fraction of the final amplitude.

    Returns
    -------
    int or None
        Period index, or None if the series never stays in the band.

    """
    phasor = np.asarray(phasor)
    final = phasor[-FINAL_PERIODS:].mean()
    err = np.abs(phasor[start:] - final)
    outside = np.flatnonzero(~(err <= band * abs(final)))
    if outside.size == 0:
        return start
    last = int(outside[-1]) + start
    return None if last >= phasor.size - 1 else last + 1


@dataclass
class PredictionResult:
    """
    Measured and predicted series of one wavelet (arrays per period, SI units).

    Attributes
    ----------
    wavelet : str
    time : numpy.ndarray
        ``(n,)`` s, sample times.
    measured : numpy.ndarray
        ``(n, 8)`` m, displacement.
    predicted : numpy.ndarray
        ``(n, 8)`` m, reconstructed predicted steady-state signal (NaN before valid periods).
    coefficients : numpy.ndarray
        ``(K, n_y)`` measured coefficients (m sqrt(samples)).
    predicted_coefficients : numpy.ndarray
        ``(K, n_y)``.
    labels : tuple of str
    step_period : int
        Period of the step.
    summary : dict
        Settling periods/times per x sensor and overall, final amplitudes.

    """

    wavelet: str
    time: np.ndarray
    measured: np.ndarray
    predicted: np.ndarray
    coefficients: np.ndarray
    predicted_coefficients: np.ndarray
    labels: tuple[str, ...]
    step_period: int
    summary: dict


def level_operator(
    rig,
    omega: float,
    config: ControllerConfig,
    level: int,
    inverse_sensors: str = DEFAULT_INVERSE_SENSORS,
):
    """
    Return the steady-state operator of one level from the FE-route model (eq. 7.6).

    ``S(z) = Gamma (G B_u)^*(z)`` with ``Gamma = G_all(1)``, the steady-state gain of all 8
    sensors, and ``(G B_u)^*`` the 5th-order least-squares inverse of the model of
    ``inverse_sensors``.

    Which sensors are inverted (decision, from the thesis's text): all 8. Section 6.4, after
    eq. 6.35: "Applying the same process in all the control axis and measuring the response at
    all the sensor locations allows a full model of the system to be constructed, from which a
    full inverse dynamic model can be evaluated"; figures 6.3-6.7 show the inverse transfer
    function at sensor 1, a rotor-end sensor that the inner-plane model does not contain
    (section 2.1: pairs "at the rotor ends and next to the active magnetic bearings"); and
    ``(.)^*`` of eq. 6.35 / 7.6 is a pseudo-inverse, which a square 4-sensor model would not
    need. Only the PID loop takes the inner sensors (section 2.6).

    With all 8 sensors a synchronous force is not a combination of the level's control
    waveforms alone, and the least-squares inverse leaves its residual outside the range of
    ``G(1)``; the inner-sensor model is square, exact at x2, x3. Settling times and final
    amplitude ratios of both (``amb-prediction``, ``--inverse-sensors inner``):
    docs/results.md#prediction; the first measurements: ``docs/controller_notes.md``
    ("Steady-state prediction"). At p >= 2 the inner model is rank deficient (the odd control
    waveforms of :func:`~amb_controller.basis.control_basis` repeat combinations of the even
    ones): the inverse is the truncated-SVD one (``rank_rtol``), without which the level-2
    prediction dominated the rebuilt signal.

    Parameters
    ----------
    rig : amb_common.rig.Rig
    omega : float
        rad/s.
    config : ControllerConfig
        Wavelet and samples per revolution.
    level : int
        Thesis level p.
    inverse_sensors : {"inner", "all"}
        Sensors of the inverted model (:data:`INVERSE_SENSORS`).

    Returns
    -------
    tuple of (numpy.ndarray, tuple of str, tuple of str)
        ``S^(0..K)`` of shape ``(K+1, n_all, n_in)``, the input (inverted-sensor) labels and
        the output (all-sensor) labels.

    """
    if inverse_sensors not in INVERSE_SENSORS:
        raise PredictionValueError(
            f"inverse_sensors must be one of {sorted(INVERSE_SENSORS)}, got {inverse_sensors!r}"
        )
    base = replace(config, levels=(level,), inverse_order=INVERSE_ORDER)
    inverted = fe_model(rig, omega, replace(base, sensors=INVERSE_SENSORS[inverse_sensors]))
    full = fe_model(rig, omega, replace(base, sensors=tuple(range(8))))
    inverse = pseudo_inverse_series(
        inverted.markov, INVERSE_ORDER, dc_weight=DC_WEIGHT, rank_rtol=RANK_RTOL
    )
    operator = series_product(dc_gain(full.markov)[None], inverse)
    return operator, tuple(inverted.measured_labels), tuple(full.measured_labels)


def apply_operator(operator: np.ndarray, q: np.ndarray) -> np.ndarray:
    """
    Return ``W_k = sum_j S^(j) Q_{k-j}`` for every period (NaN where a Q in reach is NaN).

    Parameters
    ----------
    operator : numpy.ndarray
        ``(K+1, n_out, n_in)``.
    q : numpy.ndarray
        ``(P, n_in)`` per period.

    Returns
    -------
    numpy.ndarray
        ``(P, n_out)``.

    """
    n_taps = operator.shape[0]
    padded = np.vstack([np.full((n_taps - 1, q.shape[1]), np.nan), q])
    out = np.zeros((q.shape[0], operator.shape[1]))
    for j in range(n_taps):
        out += padded[n_taps - 1 - j : n_taps - 1 - j + q.shape[0]] @ operator[j].T
    return out


def predict_run(
    rig,
    result,
    speed_hz: float,
    step_time: float,
    wavelet: str,
    inverse_sensors: str = DEFAULT_INVERSE_SENSORS,
) -> PredictionResult:
    """
    Predict the steady state of a measured run with one wavelet (module docstring).

    Parameters
    ----------
    rig : amb_common.rig.Rig
        For the FE-route model.
    result : amb_apps.closed_loop.RunResult
        The measured run (constant speed ``speed_hz``).
    speed_hz : float
        Running speed, Hz.
    step_time : float
        Time of the disturbance step, s.
    wavelet : str
        Orthogonal PyWavelets name.
    inverse_sensors : {"inner", "all"}
        Sensors of the inverted model (:func:`level_operator`).

    Returns
    -------
    PredictionResult

    """
    spr = result.samples_per_rev
    omega = 2 * math.pi * speed_hz
    config = ControllerConfig(
        wavelet=wavelet, samples_per_rev=spr, levels=LEVELS, sensors=tuple(range(8))
    )
    q, labels = coefficient_stream(result.displacement, config, rig.amb.force_limit)
    n_periods = q.shape[0]
    w = np.full_like(q, np.nan)
    index = {lab: i for i, lab in enumerate(labels)}
    for p in LEVELS:
        operator, inputs, outputs = level_operator(rig, omega, config, p, inverse_sensors)
        cols_in = np.array([index[lab] for lab in inputs])
        cols_out = np.array([index[lab] for lab in outputs])
        w[:, cols_out] = apply_operator(operator, q[:, cols_in])
    predicted = np.full((n_periods * spr, 8), np.nan)
    for c in range(8):
        rows = np.array([i for i, lab in enumerate(labels) if lab.endswith(f"/c{c}")])
        synth = np.linalg.pinv(wrapped_weights(wavelet, spr, LEVELS, c))  # (N, n_rows)
        predicted[:, c] = (w[:, rows] @ synth.T).reshape(-1)
    x = result.displacement[: n_periods * spr]
    step_period = math.floor(step_time * speed_hz + 1e-9)
    meas_ph = sync_phasors(x, spr)
    pred_ph = sync_phasors(np.nan_to_num(predicted), spr)
    pred_ph[np.isnan(w).any(axis=1)] = np.nan
    per_sensor = {}
    for c in X_SENSORS:
        km = settling_period(meas_ph[:, c], step_period)
        kp = settling_period(pred_ph[:, c], step_period)
        fm = abs(meas_ph[-FINAL_PERIODS:, c].mean())
        fp = abs(pred_ph[-FINAL_PERIODS:, c].mean())
        per_sensor[f"x{c // 2 + 1}"] = {
            "measured_settling_s": _seconds(km, step_period, speed_hz),
            "predicted_settling_s": _seconds(kp, step_period, speed_hz),
            "measured_final_1x": float(fm),
            "predicted_final_1x": float(fp),
            "amplitude_ratio": float(fp / fm) if fm > 0 else None,
        }
    summary = {
        "sensors": per_sensor,
        "measured_settling_s": _worst(s["measured_settling_s"] for s in per_sensor.values()),
        "predicted_settling_s": _worst(s["predicted_settling_s"] for s in per_sensor.values()),
        "period_s": 1.0 / speed_hz,
    }
    return PredictionResult(
        wavelet, result.time[: n_periods * spr], x, predicted, q, w, labels, step_period, summary
    )


def _seconds(k: int | None, step_period: int, speed_hz: float) -> float | None:
    return None if k is None else (k + 1 - step_period) / speed_hz


def _worst(values) -> float | None:
    values = list(values)
    return None if any(v is None for v in values) else max(values)


def plot_prediction(pr: PredictionResult, out: Path, step_time: float) -> list[Path]:
    """
    Draw figure 7.2 (measured x and predicted steady state) and 7.3-7.5 (coefficients).

    Parameters
    ----------
    pr : PredictionResult
    out : Path
        Folder.
    step_time : float
        s, marked on the plots.

    Returns
    -------
    list of Path

    """
    # heavy, optional: matplotlib, only for the figures
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = pr.time
    fig, axes = plt.subplots(4, 2, figsize=(10, 8), sharex=True, sharey=True)
    for row, c in enumerate(X_SENSORS):
        name = f"x{c // 2 + 1}"
        axes[row, 0].plot(t, pr.measured[:, c] * 1e6, lw=0.6)
        axes[row, 1].plot(t, pr.predicted[:, c] * 1e6, lw=0.6, color="tab:red")
        s = pr.summary["sensors"][name]
        for col, key in ((0, "measured_settling_s"), (1, "predicted_settling_s")):
            if s[key] is not None:
                axes[row, col].axvline(step_time + s[key], color="k", ls=":", lw=0.8)
            axes[row, col].axvline(step_time, color="0.6", lw=0.8)
        axes[row, 0].set_ylabel(f"{name} (um)")
    axes[0, 0].set_title("(a-d) measured")
    axes[0, 1].set_title("(e-h) predicted steady state")
    axes[-1, 0].set_xlabel("time (s)")
    axes[-1, 1].set_xlabel("time (s)")
    fig.suptitle(
        f"Step synchronous force 200 N at 22 Hz, x axis, {pr.wavelet} (dotted: 5 % settling)"
    )
    fig.tight_layout()
    p1 = out / f"prediction_{pr.wavelet}_signal.png"
    fig.savefig(p1, dpi=110)
    plt.close(fig)

    n = pr.coefficients.shape[0]
    tk = (np.arange(n) + 1) / (1.0 / (t[1] - t[0]) / (pr.measured.shape[0] // n))
    fig, axes = plt.subplots(len(LEVELS), 4, figsize=(12, 7), sharex=True)
    for r, p in enumerate(LEVELS):
        for col, c in enumerate(X_SENSORS):
            i = pr.labels.index(f"p{p}/q1/even/c{c}")
            ax = axes[r, col]
            ax.plot(tk, pr.coefficients[:, i] * 1e6, "k--", lw=0.8, label="measured")
            ax.plot(tk, pr.predicted_coefficients[:, i] * 1e6, "r-", lw=1.0, label="predicted")
            ax.set_title(f"x_{{{p},1}} sensor x{c // 2 + 1} ({2 ** (p - 1)} x)", fontsize=9)
        axes[r, 0].set_ylabel("um sqrt(samples)")
    axes[0, 0].legend(fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    fig.suptitle(f"{pr.wavelet} coefficients (even quadrature): figures 7.3-7.5 style")
    fig.tight_layout()
    p2 = out / f"prediction_{pr.wavelet}_coefficients.png"
    fig.savefig(p2, dpi=110)
    plt.close(fig)
    return [p1, p2]


def run_prediction(
    wavelets=WAVELETS,
    samples_per_rev: int = 64,
    scenario_path=None,
    inverse_sensors=DEFAULT_INVERSE_SENSORS,
):
    """
    Run the 22 Hz step synchronous force (PID only) once and predict with each wavelet.

    Returns
    -------
    tuple of (dict of str to PredictionResult, float)
        Results per wavelet and the step time (s).

    """
    rig = load_rig()
    scenario = load_scenario(
        scenario_path or config_file("scenarios/sync_force_200N_22Hz.yaml"), rig
    )
    steps = [e.time for e in scenario.events if e.kind == "sync_force"]
    if not steps:
        raise PredictionValueError(f"scenario {scenario.name!r} has no sync_force event")
    cfg = ControllerConfig(samples_per_rev=samples_per_rev, controller="none")
    result = run_closed_loop(rig, scenario, cfg)
    out = {
        w: predict_run(rig, result, scenario.speed_hz, steps[0], w, inverse_sensors)
        for w in wavelets
    }
    return out, steps[0]


def main(argv=None) -> int:
    """Predict, print the settling times, write PNGs and ``prediction.json``."""
    ap = argparse.ArgumentParser(
        prog="python -m amb_apps.prediction_cli",
        description="Steady-state prediction (thesis 7.4.1) on the 22 Hz step synchronous force.",
    )
    ap.add_argument("--out", type=Path, required=True, help="output folder (created)")
    ap.add_argument("--wavelets", nargs="+", default=list(WAVELETS))
    ap.add_argument("--json", action="store_true", help="print the JSON result")
    ap.add_argument(
        "--inverse-sensors",
        choices=sorted(INVERSE_SENSORS),
        default=DEFAULT_INVERSE_SENSORS,
        help="sensors of the inverted model: all 8 (default, thesis section 6.4) or the inner "
        "planes 2, 3",
    )
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    results, step = run_prediction(args.wavelets, inverse_sensors=args.inverse_sensors)
    summary = {w: pr.summary for w, pr in results.items()}
    (args.out / "prediction.json").write_text(json.dumps(summary, indent=1))
    for pr in results.values():
        plot_prediction(pr, args.out, step)
    if args.json:
        print(json.dumps(summary, indent=1))
    else:
        for w, s in summary.items():
            print(
                f"{w}: measured settles {s['measured_settling_s']} s, predicted "
                f"{s['predicted_settling_s']} s after the step",
                file=sys.stdout,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
