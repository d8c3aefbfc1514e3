"""
amb-compare pieces: metrics on synthetic runs with known answers, the model perturbation
against its closed form, the fault-triggered engagement, figure 8.3 for i = 1, timing.
"""

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from amb_apps.compare_runs import command_timing, run_metrics
from amb_controller.baselines import perturb_model
from amb_controller.errors import ControllerValueError
from amb_controller.model_file import WaveletModel
from amb_controller.stability import exponential_stability_map

SPR = 16


def _run(envelope, force=None):
    """Synthetic RunResult: x2 = envelope[k] cos(theta) per revolution k, fault at rev 2."""
    n = len(envelope) * SPR
    theta = 2 * np.pi * np.arange(n) / SPR
    x = np.zeros((n, 8))
    x[:, 2] = np.repeat(envelope, SPR) * np.cos(theta)
    wf = np.zeros((n, 4)) if force is None else force
    return SimpleNamespace(
        samples_per_rev=SPR, displacement=x, fault_time=2.0, wavelet_force=wf,
        contact=np.zeros((n, 1), bool), time=np.arange(n) / SPR,
    )  # fmt: skip


def test_revolutions_to_10_percent_and_peak_of_a_geometric_decay():
    env = np.concatenate([[0.0, 0.0], 100e-6 * 0.5 ** np.arange(30)])
    m = run_metrics(_run(env), speed_hz=1.0)
    assert m["peak"] == pytest.approx(100e-6, rel=1e-12)
    # 0.5^k > 0.1 for k <= 3: revolutions 0..3 after the fault are above 10 %
    assert m["revs_to_10"] == 4
    assert m["revs_below_10pct_pid"] is None  # no PID-only amplitude given
    # against a PID-only amplitude of 400 um: 100 * 0.5^k > 40 for k <= 1
    assert run_metrics(_run(env), speed_hz=1.0, pid_steady=400e-6)["revs_below_10pct_pid"] == 2


def test_never_settling_run_reports_not_reached_and_attenuation_in_db():
    env = np.concatenate([[0.0, 0.0], np.full(30, 50e-6)])
    m = run_metrics(_run(env), speed_hz=1.0, pid_steady=500e-6)
    assert m["revs_to_10"] is None
    assert m["revs_below_10pct_pid"] == 0  # 50 um is 10 % of 500: never above it
    assert m["steady_1x"] == pytest.approx(50e-6, rel=1e-9)
    assert m["attenuation_db"] == pytest.approx(-20.0, abs=1e-9)


def test_force_metrics_peak_of_the_bearing_resultant_and_rms_after_fault():
    n = 10 * SPR
    f = np.zeros((n, 4))
    f[2 * SPR :, 0] = 30.0
    f[2 * SPR :, 1] = 40.0
    m = run_metrics(_run(np.ones(10) * 1e-6, f), speed_hz=1.0)
    assert m["peak_force"] == pytest.approx(50.0)
    assert m["rms_force"] == pytest.approx(math.sqrt((30.0**2 + 40.0**2) / 4))


def test_1x_settling_is_measured_apart_from_a_harmonic_left_after_it():
    # 1 x decays as 0.5^k from 100 um; a steady 3 x of 15 um (15 % of the peak) stays
    n_rev = 32
    env = np.concatenate([[0.0, 0.0], 100e-6 * 0.5 ** np.arange(n_rev - 2)])
    run = _run(env)
    theta = 2 * np.pi * np.arange(n_rev * SPR) / SPR
    run.displacement[2 * SPR :, 2] += 15e-6 * np.cos(3 * theta[2 * SPR :])
    m = run_metrics(run, speed_hz=1.0)
    assert m["revs_to_10"] is None  # the displacement never falls below 10 % of its peak
    assert m["revs_to_10_1x"] == 4  # the 1 x amplitude does, as 0.5^k: k = 0..3 above 10 %
    assert m["peak_1x"] == pytest.approx(100e-6, rel=1e-9)


def _row(peak, revs, revs_1x, non1x, force=40.0, radius=None, peak_1x=None):
    return {
        "peak": peak, "revs_to_10": revs, "revs_to_10_1x": revs_1x, "non1x_um": non1x,
        "harmonics_um": {"2x": 0.2, "3x": 6.6, "5x": 2.2, "7x": 2.5}, "peak_force": force,
        "peak_1x": peak if peak_1x is None else peak_1x, "model_radius": radius,
        "contacts": 0, "rms_force": 10.0,
    }  # fmt: skip


def test_harmonic_content_removes_a_decaying_1x_revolution_by_revolution():
    from amb_apps.compare_runs import harmonic_content

    n_rev = 12
    theta = 2 * np.pi * np.arange(n_rev * SPR) / SPR
    decay = np.repeat(80e-6 * 0.7 ** np.arange(n_rev), SPR)  # 1 x still decaying
    x = np.zeros((n_rev * SPR, 8))
    x[:, 2] = decay * np.cos(theta) + 5e-6 * np.cos(3 * theta + 0.4) + 2e-6 * np.sin(5 * theta)
    h = harmonic_content(SimpleNamespace(samples_per_rev=SPR, displacement=x))
    assert h["harmonics_um"]["3x"] == pytest.approx(5.0, rel=1e-9)
    assert h["harmonics_um"]["5x"] == pytest.approx(2.0, rel=1e-9)
    assert h["harmonics_um"]["2x"] == pytest.approx(0.0, abs=1e-9)
    peak = np.abs(5e-6 * np.cos(3 * theta + 0.4) + 2e-6 * np.sin(5 * theta)).max() * 1e6
    assert h["non1x_um"] == pytest.approx(peak, rel=1e-9)


def test_verdict_says_where_the_wavelet_controller_wins_and_loses_and_why():
    from amb_apps.compare_report import verdict

    table = {
        "mass_loss_1st": {
            "pid": _row(141e-6, None, None, 0.8),
            "wavelet_i1": _row(94.7e-6, None, 12, 12.2, radius=0.798, peak_1x=87.0e-6),
            "harmonic_i1": _row(91.1e-6, 10, 10, 0.87, radius=0.783, peak_1x=85.4e-6),
            "synchronous_i1": _row(111.4e-6, 9, 9, 0.86),
        },
        "sync_150N_3rd": {"wavelet_i1": _row(1e-3, None, None, 1.0)},
    }
    text = "\n".join(verdict(table, 1000.0))
    assert "vs harmonic_i1: peak 94.7 vs 91.1 um, LOSES by 4.0 %" in text
    assert "1 x amplitude: 87.0 vs 85.4 um" in text and "0.798 vs 0.783" in text
    assert "vs synchronous_i1: peak 94.7 vs 111.4 um, WINS by 15.0 %" in text
    assert "settles to 10 % in 12 revolutions (harmonic_i1: 10)" in text
    assert "12.2 um of non-1 x displacement" in text and "above 10 % of its peak (9.5 um)" in text
    assert "odd harmonics (3x 6.6, 5x 2.2, 7x 2.5 um)" in text
    assert "the limit was not reached" in text
    assert "sync_150N_3rd" not in text  # only the mass-loss cases carry the target
    assert "wavelet_sin_i1" not in text
    sin = _row(90.1e-6, 12, 11, 0.1)
    sin["revs_below_10pct_pid"] = 11
    table["mass_loss_1st"]["wavelet_sin_i1"] = sin
    table["mass_loss_1st"]["harmonic_i1"]["revs_below_10pct_pid"] = 11
    text = "\n".join(verdict(table, 1000.0))
    assert (
        "wavelet_sin_i1 (the same law and coefficients, a 1 x sinusoidal force): peak 90.1" in text
    )
    assert "non-1 x over the last 10 revolutions 0.1 um (wavelet_i1 12.2)" in text
    assert "harmonic_i1 91.1 um / 11, synchronous_i1 111.4 um / not reached" in text
    table["mass_loss_1st"]["wavelet_i1"]["peak_force"] = 1000.0
    assert "the limit was reached" in "\n".join(verdict(table, 1000.0))
    rows = table["mass_loss_1st"]
    rows["pid"]["steady_1x"] = 140e-6
    rows["wavelet_i1"]["revs_below_10pct_pid"] = None
    pred = _row(88.0e-6, 5, 5, 0.1)
    pred.update(revs_below_10pct_pid=5, steady_1x=0.7e-6, peak_to_limit=3.52)
    rows["predictive_i1"] = pred
    text = "\n".join(verdict(table, 1000.0))
    assert "predictive_i1 (receding horizon" in text and "peak 88.0 um (3.52 x limit_i1)" in text
    assert "after 5 revolutions, steady 1 x 0.5 % of PID only's" in text
    # 88.0 beats wavelet_i1 (94.7) and synchronous_i1 (111.4), not harmonic_i1 (91.1 > 88: it
    # does) nor wavelet_sin_i1 (90.1 > 88: it does); every row is slower than 5 revolutions
    assert "lower peak than 4 of 4 rows at i = 1, sooner below than 4 of 4." in text
    rows["harmonic_i1"]["peak"] = 80e-6
    rows["harmonic_i1"]["revs_below_10pct_pid"] = 4
    text = "\n".join(verdict(table, 1000.0))
    assert "lower peak than 3 of 4 rows at i = 1 (not harmonic_i1)" in text
    assert "sooner below than 3 of 4 (not harmonic_i1)." in text


def test_the_i2_rows_are_set_against_the_baselines_at_i2():
    """The mass_loss_2nd figures of 2026-12-06's amb-compare: the early action at i = 2
    (194.9 um) is below the harmonic baseline at its own delay only if that row exists; at
    i = 1 (188.9 um) the baseline had the delay advantage. Each i = 2 row is named where it
    loses, and no i = 1 row counts among the i = 2 ones."""
    from amb_apps.compare_report import verdict

    def row(peak, revs):
        r = _row(peak, revs, revs, 0.8)
        r.update(revs_below_10pct_pid=revs, steady_1x=0.5e-6)
        return r

    rows = {
        "pid": row(252.3e-6, None),
        "wavelet_i1": row(197.8e-6, None),
        "harmonic_i1": row(188.9e-6, 9),
        "predictive_early_i2": row(194.9e-6, 5),
        "predictive_i2": row(218.0e-6, 7),
        "harmonic_i2": row(200.0e-6, 10),
        "synchronous_i2": row(190.0e-6, 4),
    }
    rows["pid"]["steady_1x"] = 250e-6
    text = "\n".join(verdict({"mass_loss_2nd": rows}, 1000.0))
    early = next(line for line in text.splitlines() if line.startswith("- predictive_early_i2"))
    assert "the early action on a sudden unbalance" in early
    assert "lower peak than 2 of 3 rows at i = 2 (not synchronous_i2)" in early
    assert "sooner below than 2 of 3 (not synchronous_i2)." in early
    law = next(line for line in text.splitlines() if line.startswith("- predictive_i2"))
    assert "lower peak than 0 of 3 rows at i = 2" in law
    assert "harmonic_i1" not in early and "harmonic_i1" not in law


def test_rows_whose_own_model_predicts_divergence_are_flagged():
    from amb_apps.compare_report import _notes

    rows = {
        "pid": _row(1e-4, None, None, 1.0),
        "wavelet_i1": _row(3e-2, None, None, 1.0, radius=1.027),
        "wavelet_i1_8sensors": _row(1e-5, 5, 5, 1.0, radius=0.76),
    }
    rows["harmonic_i1"] = _row(6e-3, None, None, 1.0, radius=0.991)
    text = "\n".join(_notes("sync_150N_3rd", rows))
    assert "wavelet_i1: exact closed-loop spectral radius 1.027 >= 1" in text
    assert "predicted before the run (peak 30.00 mm in the run)" in text
    assert "harmonic_i1: radius 0.991 on its own FE model, stable only by 0.009" in text
    assert "wavelet_i1_8sensors 0.760" in text and "8 sensors" in text
    rows["wavelet_i2"] = _row(12e-3, None, None, 1.0, radius=0.928)  # diverged, model stable
    notes = "\n".join(_notes("contact_case2", rows))
    assert "wavelet_i2: peak 12.00 mm in the run although its own FE model gives" in notes
    assert "no dynamic model" not in notes
    assert "wavelet_i1_8sensors: exact" not in text and "harmonic_i1 0.991" not in text
    assert _notes("mass_loss_1st", {"wavelet_i1": _row(1e-4, 3, 3, 1.0, radius=0.8)}) == []
    refused = _row(1e-4, None, None, 1.0, radius=1.001)
    refused["refused"] = "closed loop on its own model has spectral radius 1.001 >= ..."
    notes = "\n".join(_notes("sync_150N_3rd", {"pid": rows["pid"], "wavelet_i1": refused}))
    assert "wavelet_i1: not set ACTIVE, the row is PID only: closed loop on its own" in notes
    assert "predicted before the run" not in notes


def _pair_model():
    rng = np.random.default_rng(0)
    markov = rng.normal(size=(3, 2, 2))
    return WaveletModel(
        markov=markov, inverse=np.zeros((1, 2, 2)), wavelet="haar", samples_per_rev=4,
        omega=1.0, levels=(1,), measured_labels=("p1/q1/even/c2", "p1/q1/odd/c2"),
        control_labels=("p1/q1/even/c0", "p1/q1/odd/c0"),
    )  # fmt: skip


def test_perturbation_scales_and_rotates_the_measured_phasor():
    model = _pair_model()
    out = perturb_model(model, 1.3, math.radians(30), inverse_order=0)
    y = model.markov[:, 0] - 1j * model.markov[:, 1]
    y_out = out.markov[:, 0] - 1j * out.markov[:, 1]
    np.testing.assert_allclose(y_out, 1.3 * np.exp(1j * math.radians(30)) * y, atol=1e-12)
    # the inverse is rebuilt from the perturbed Markov parameters, not kept from the model
    from amb_controller.inverse import pseudo_inverse_series

    np.testing.assert_array_equal(out.inverse, pseudo_inverse_series(out.markov, 0))
    assert not np.allclose(out.inverse, pseudo_inverse_series(model.markov, 0))
    with pytest.raises(ControllerValueError, match="gain must be > 0"):
        perturb_model(model, -1.0)


def test_figure_8_3_one_period_delay_admits_the_thesis_setting_and_more():
    # i = 1: characteristic polynomial (z - v) + w (z - 1)^2 = w z^2 + (1 - 2w) z + (w - v);
    # Jury conditions for a z^2 + b z + c (a > 0): |c| < a, a + b + c > 0, a - b + c > 0.
    w = np.linspace(0.05, 0.95, 19)
    v = np.linspace(0.0, 0.95, 20)
    stable = exponential_stability_map(w, v, 1)
    ww, vv = np.meshgrid(w, v)
    a, b, c = ww, 1 - 2 * ww, ww - vv
    jury = (np.abs(c) < a) & (a + b + c > 0) & (a - b + c > 0)
    boundary = np.isclose(np.abs(c), a) | np.isclose(a - b + c, 0) | np.isclose(a + b + c, 0)
    assert np.array_equal(stable[~boundary], jury[~boundary])
    s1 = exponential_stability_map(w, v, 1).sum()
    s2 = exponential_stability_map(w, v, 2).sum()
    assert s1 > s2  # one-period delay: a larger stable region than the thesis's i = 2


def test_command_evaluation_is_a_small_fraction_of_a_period():
    t = command_timing(64, repeats=200)
    period_67hz = 1 / 67.0  # s, fastest thesis experiment speed (second bending)
    for name, v in t.items():
        assert v["median_s"] < 0.05 * period_67hz, (name, v)


def test_engage_on_starts_off_and_engages_at_the_detected_mass_loss(rig, first_critical):
    from amb_apps.closed_loop import fe_model, run_closed_loop
    from amb_controller.config import ControllerConfig

    sc = replace(first_critical, duration=5.0)
    cfg = ControllerConfig(samples_per_rev=32, delay_periods=1)
    model = fe_model(rig, 2 * math.pi * sc.speed_hz, cfg)
    res = run_closed_loop(rig, sc, cfg, model, fault_monitor=True, engage_on=(1,))
    onset = int(2.0 * sc.speed_hz * 32)
    assert np.all(res.wavelet_force[:onset] == 0)  # PID only before the fault
    assert np.abs(res.wavelet_force[onset:]).max() > 1.0
    assert any(e["fault_type"] == "MASS_LOSS" for e in res.fault_events)
    with pytest.raises(ControllerValueError, match="fault_monitor"):
        run_closed_loop(rig, sc, cfg, model, engage_on=(1,))


def test_residual_after_1x_is_the_third_harmonic_left_on_a_1x_orbit():
    from amb_apps.compare_runs import residual_after_1x

    n = 20 * SPR
    theta = 2 * np.pi * np.arange(n) / SPR
    x = np.zeros((n, 8))
    x[:, 2] = 50e-6 * np.cos(theta + 0.3) + 4e-6 * np.cos(3 * theta)  # 1 x removed, 3 x left
    x[:, 5] = 30e-6 * np.sin(theta)
    run = SimpleNamespace(samples_per_rev=SPR, displacement=x)
    assert residual_after_1x(run) == pytest.approx(4e-6, rel=1e-9)


def test_model_radius_predicts_that_the_third_critical_rows_settle():
    """The radius computed before any run (``model_radius``) is the one the run's pipeline
    checks, and it predicts the run. Reference: the simulator. At the third critical speed
    the inner-probe eq.-8.10 rows (wavelet and harmonic) have radius below 1 on their own
    models (measured 0.92 and 0.86) and their runs, 150 N step included, end without a
    contact at a tenth of PID alone's steady 1 x or less (measured 3.4 and 167 um). The
    loop that diverges there (the outer probes) is in ``test_third_critical.py``."""
    from amb_apps.compare_cases import Matrix
    from amb_apps.compare_runs import model_radius, run_row
    from amb_common.paths import config_file

    matrix = Matrix(config_file("scenarios"), 32, None, True)
    speed = matrix.scenarios["sync_150N_3rd"].speed_hz
    pid = run_metrics(run_row(matrix, "sync_150N_3rd", "pid"), speed)
    for name in ("wavelet_i1", "harmonic_i1"):
        radius = model_radius(matrix, name, "sync_150N_3rd")
        assert radius < 1.0
        run = run_row(matrix, "sync_150N_3rd", name)
        assert run.model_radius == pytest.approx(radius, rel=1e-9) and run.refused == ""
        m = run_metrics(run, speed)
        assert m["contacts"] == 0 and m["steady_1x"] < 0.1 * pid["steady_1x"], name
    assert 0.667 < model_radius(matrix, "wavelet_i1", "mass_loss_1st") < 0.9  # ideal 2/3
    assert model_radius(matrix, "pid", "mass_loss_1st") is None
    assert model_radius(matrix, "synchronous_i1", "mass_loss_1st") is None


def test_limit_row_replayed_over_the_run_keeps_the_programs_peak():
    # the limit's force, continued periodically to the run's end and replayed on the rig,
    # is measured like every row: its peak is the linear program's, which covers 4
    # revolutions of the periodic tail; after them the response may still drift towards its
    # periodic steady state, by less than 1 % of the peak here (0.15 % measured)
    from amb_apps.compare_cases import Matrix
    from amb_apps.compare_runs import run_limit
    from amb_common.paths import config_file
    from amb_plant_sim.control_limit import control_limit

    matrix = Matrix(config_file("scenarios"), 32, None, quick=True)
    result = run_limit(matrix, "mass_loss_1st", 2, settle=False)
    sc = matrix.scenarios["mass_loss_1st"]
    lim = control_limit(matrix.rig, sc, 32, result.fault_time, 2, settle=False)
    m = run_metrics(result, sc.speed_hz)
    assert lim.peak * (1 - 1e-6) <= m["peak"] <= lim.peak * 1.01
    assert m["contacts"] == 0
    assert m["peak_force"] <= matrix.force_limit * (1 + 1e-9)


def test_controllers_their_own_model_says_diverge_run_as_pid_only_at_the_third_critical():
    """Issue 18, "never worse than PID": a controller whose closed loop on its own model has
    radius above 1 refuses to go ACTIVE and the run is PID's, sample for sample. The case:
    the third critical speed with the outer probes (at the shaft's ends) and a first-order
    inverse (amb-compare's settings otherwise), where the eq.-8.10 loop and the harmonic
    baseline's have radius above 1 (measured 1.065 and 1.051; that eq.-8.10 loop diverges in
    the simulator, ``test_third_critical.py``). The inner-probe rows there, and at the first
    critical, go ACTIVE."""
    from amb_apps.closed_loop import run_closed_loop
    from amb_apps.compare_cases import SPECS, Matrix
    from amb_apps.compare_runs import run_row
    from amb_common.paths import config_file

    matrix = Matrix(config_file("scenarios"), 32, None, True)
    scenario = matrix.scenarios["sync_150N_3rd"]
    pid = run_row(matrix, "sync_150N_3rd", "pid")
    assert pid.refused == ""
    for name in ("wavelet_i1", "harmonic_i1"):
        spec = SPECS[name]
        config = replace(matrix.config(spec, scenario), sensors=(0, 1, 6, 7), inverse_order=1)
        run = run_closed_loop(matrix.rig, scenario, config, matrix.model(spec, scenario, config))
        assert run.model_radius > 1.0, name
        assert "spectral radius" in run.refused and "max_model_radius" in run.refused
        assert not np.any(run.wavelet_force)
        np.testing.assert_array_equal(run.displacement, pid.displacement)
    assert run_row(matrix, "sync_150N_3rd", "wavelet_i1").refused == ""
    assert run_row(matrix, "mass_loss_1st", "wavelet_i1").refused == ""


def _early_and_plain(key: str, delay: int):
    """amb-compare's scenario ``key`` (--quick, 64 samples/rev) run with the predictive law at
    ``delay`` with and without the early action: (scenario, early run, plain run, the one
    detection)."""
    from amb_apps.compare_cases import SPECS, Matrix
    from amb_common.paths import config_file

    matrix = Matrix(config_file("scenarios"), 64, None, True)
    holder = {}

    def keep(loop):
        holder["loop"] = loop
        return False

    early = matrix.run(SPECS[f"predictive_early_i{delay}"], key, stop=keep)
    plain = matrix.run(SPECS[f"predictive_i{delay}"], key)
    (found,) = holder["loop"].pipeline.early.detections
    return matrix.scenarios[key], early, plain, found


def test_early_action_finds_the_scenario_s_loss_and_beats_the_period_rate_law():
    """Issue 18 item 4 on the simulated rig (mass_loss_1st: 430 g cm at D1, 64 samples/rev).

    The reference is the scenario's own fault: the estimate must find its disk and
    unbalance (4.3e-3 kg m) in the fault's own period. 5 % covers a loss late in its period:
    with seven samples of it (an earlier rig model's speed) the likelihood ratio was ~1.6e3
    (energy over noise variance), a relative standard deviation of 1 / sqrt(1.6e3) = 2.5 %, so
    5 % is two of them; here 18 samples carry it (ratio ~1.4e6, measured error 0.1 %). Its
    force, from the next period, must lower the peak of the same predictive law without it by
    30 % or more (measured 90.4 -> 47.1 um, 48 %).
    """
    scenario, early, plain, found = _early_and_plain("mass_loss_1st", 1)
    loss = next(e for e in scenario.events if e.kind == "mass_loss")
    fs = scenario.speed_hz * 64
    assert found.plane == loss.get("disk") and found.acted
    assert found.me == pytest.approx(loss.get("me"), rel=0.05)
    assert abs(found.onset_sample - loss.time * fs) <= 2
    assert found.period == int(loss.time * fs) // 64
    speed = scenario.speed_hz
    assert run_metrics(early, speed)["peak"] < 0.7 * run_metrics(plain, speed)["peak"]


def test_early_action_finds_the_bearing_s_synchronous_force_at_the_third_critical():
    """Issue 18 item 4 with the thesis's section-8.5.2 disturbance (sync_150N_3rd).

    A 150 N synchronous force through AMB 1 is the unbalance ``me = F / Omega^2`` at the
    bearing's node (eq. 3.3): the estimate must name the bearing and give back 150 N (5 %,
    as for the mass loss above; the likelihood ratio here is ~2.5e5) from the onset's period,
    and its force must lower the peak of the predictive law without it (measured 149.7 ->
    110.6 um at i = 2; 3 % asked).
    """
    scenario, early, plain, found = _early_and_plain("sync_150N_3rd", 2)
    step = next(e for e in scenario.events if e.kind == "sync_force")
    omega = 2 * math.pi * scenario.speed_hz
    assert found.plane == f"AMB{step.get('bearing')}" and found.acted
    assert found.me * omega**2 == pytest.approx(step.get("amplitude"), rel=0.05)
    assert abs(found.onset_sample - step.time * scenario.speed_hz * 64) <= 2
    speed = scenario.speed_hz
    assert run_metrics(early, speed)["peak"] < 0.97 * run_metrics(plain, speed)["peak"]


@pytest.mark.parametrize(
    ("factor", "single"),
    [
        # between the bank's models (1.0721 and 1.0829 of the nominal speed: 0.27 % from one);
        # measured (reachable peak) 99.9 -> 67.6 um
        (1.075, False),
        # the exact model of the plant's speed: measured 74.7 -> 47.3 um
        (0.95, True),
    ],
)
def test_early_action_off_the_nominal_speed(factor, single):
    """Issue 18 item 4 off the model's speed (mass_loss_1st, 64 samples/rev, the plant at
    ``factor`` times the scenario's speed). References as in the test above: the scenario's
    own loss (disk, 4.3e-3 kg m within 5 %) and the same predictive law without the early
    action, under the same plant.

    The early action's force starts in the period after the fault's, so the peak it can lower
    is that of the revolutions after the fault's own; with the fault early in its period (at
    1.075 x the speed, 7 % into it) the run's peak is in the fault's own revolution, the same
    for both runs (92.9 um), which no delayed force can change. Asked: the reachable peak 20 %
    lower (measured 32 % and 37 %), and the run's peak no higher.
    """
    from dataclasses import replace

    from amb_apps.compare_cases import SPECS, Matrix
    from amb_apps.plant_models import early_action_model
    from amb_common.paths import config_file
    from amb_controller.metrics import inner_revolution_peaks

    matrix = Matrix(config_file("scenarios"), 64, None, True)
    scenario = matrix.scenarios["mass_loss_1st"]
    hz = scenario.speed_hz * factor
    kw = {}
    if single:
        kw["early_model"] = early_action_model(matrix.rig, replace(scenario, speed_hz=hz), 64)
    holder = {}

    def keep(loop):
        holder["loop"] = loop
        return False

    early = matrix.run(SPECS["predictive_early_i1"], "mass_loss_1st", speed_hz=hz, stop=keep, **kw)
    plain = matrix.run(SPECS["predictive_i1"], "mass_loss_1st", speed_hz=hz)
    (found,) = holder["loop"].pipeline.early.detections
    loss = next(e for e in scenario.events if e.kind == "mass_loss")
    assert found.plane == loss.get("disk") and found.acted
    assert found.me == pytest.approx(loss.get("me"), rel=0.05)
    k_f = math.floor(loss.time * hz)  # the fault's own revolution

    def reachable(run):
        return inner_revolution_peaks(run.displacement, 64, k_f + 1).max()

    assert reachable(early) < 0.8 * reachable(plain)
    assert run_metrics(early, hz)["peak"] <= run_metrics(plain, hz)["peak"] * (1 + 1e-9)


def test_the_monitor_does_not_take_the_early_action_s_force_kink_for_a_contact():
    """Issue 19 (the fault monitor in the loop): the early action's transient force unsmoothed
    (``transient_smoothing`` 0) steps by hundreds of newtons in one sample at the start of its
    period and rings the finest level like a contact. Reference: the simulator's truth (no
    contact). With the kink rule (``control_kink``) the monitor reports the loss and no
    contact; with it off (a threshold no force reaches) it called one (measured: a burst
    whose onset is the sample of a 321 N step)."""
    from amb_apps.bound_cli import moved
    from amb_apps.compare_cases import SPECS, Matrix
    from amb_common.paths import config_file
    from amb_controller.early_action import EarlyActionConfig
    from amb_fault_monitor.config import MonitorConfig

    matrix = Matrix(config_file("scenarios"), 64, None, True)
    matrix.scenarios["mass_loss_1st"] = moved(matrix.scenarios["mass_loss_1st"], 64, 0.25)[0]
    kw = {"fault_monitor": True, "early_config": EarlyActionConfig(transient_smoothing=0.0)}

    def kinds(**more):
        run = matrix.run(SPECS["predictive_early_i1"], "mass_loss_1st", **kw, **more)
        assert not run.contact.any()  # the truth: no contact in this run
        return [e["fault_type"] for e in run.fault_events]

    assert kinds() == ["MASS_LOSS"]
    off = MonitorConfig(samples_per_rev=64, control_kink=1e5)
    assert "AUX_BEARING_CONTACT" in kinds(monitor_config=off)


def test_the_early_action_holds_the_law_instead_of_doubling_its_answer():
    """Issue 18, robustness at i = 2 (``mass_loss_1st``, amb-compare's "gain -30%": both the
    coefficient model and the early model believe the force path 30 % weaker than it is).
    Reference: the same predictive law without the early action, under the same model error.
    With the law held while its measurements do not show the plan (``hold_law``), the peak is
    no higher than the law's alone; unheld, the law and the plan both answered the change in
    the same period (measured 103.6 um against 93.9; held 82.6), which the second assertion
    checks is still so (the case is one where the hold matters)."""
    from amb_apps.compare_cases import SPECS, Matrix
    from amb_apps.compare_runs import perturb_early_model, perturb_model
    from amb_common.paths import config_file
    from amb_controller.early_action import EarlyActionConfig

    matrix = Matrix(config_file("scenarios"), 64, None, True)
    key = "mass_loss_1st"
    scenario = matrix.scenarios[key]

    def peak(name, **kw):
        spec = SPECS[name]
        config = matrix.config(spec, scenario)
        model = perturb_model(matrix.model(spec, scenario, config), 0.7, 0.0, config.inverse_order)
        if spec.early:
            kw["early_model"] = perturb_early_model(matrix.early_model(scenario, config), 0.7, 0.0)
        return run_metrics(matrix.run(spec, key, model=model, **kw), scenario.speed_hz)["peak"]

    alone = peak("predictive_i2")
    assert peak("predictive_early_i2") <= alone
    assert peak("predictive_early_i2", early_config=EarlyActionConfig(hold_law=False)) > alone


def test_quick_limit_rows_leave_out_the_columns_their_settling_objective_decides():
    """``--quick`` solves the limit rows without the settling objective (amb_apps.compare_runs,
    ``SETTLE_SKIPPED``): their steady, settling and residual columns are shown as "-", with a
    note, not as the limit's; a full run's limit row shows them."""
    from amb_apps.compare_report import markdown
    from amb_apps.compare_runs import SETTLE_SKIPPED

    full = _row(25.6e-6, 3, 3, 0.1)
    full.update(
        revs_below_10pct_pid=2, steady_1x=0.4e-6, attenuation_db=-40.0, residual_um=13.33,
        peak_to_limit=1.0,
    )  # fmt: skip
    quick = {**full, **dict.fromkeys(SETTLE_SKIPPED), "settle_skipped": True}
    speeds = {"mass_loss_1st": 9.72}

    def limit_line(row: dict) -> tuple[str, str]:
        text = markdown({"table": {"mass_loss_1st": {"limit_i1": row}}}, {}, speeds)
        return text, next(ln for ln in text.splitlines() if ln.startswith("| limit_i1"))

    text, line = limit_line(full)
    assert "| 25.6 | 3 | 3 | 2 | 0.40 | -40.0 | 40 | 10.0 | 0 | 13.33 | - | 1.00 |" in line
    assert "--quick" not in text
    text, line = limit_line(quick)
    assert "| 25.6 | - | - | - | - | - | 40 | 10.0 | 0 | - | - | 1.00 |" in line
    assert "--quick: the limit rows replay the least force of the optimal peak" in text
