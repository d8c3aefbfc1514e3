"""
PID closed loop (eq. 2.45-2.48, Table 2.3), AMB law (eq. 2.33-2.40) and the calibration.

External references: Table 2.3 (PID law), section 2.3 (K_z = 2240 N/mm, K_i = 572 N/A from
Table 2.2), the thesis's 11, 18, 29, 67 Hz, and the numbers recorded in config/rig.yaml.
"""

import math
from dataclasses import replace

import numpy as np
import pytest

from amb_common.rig import PidGains
from amb_plant_sim import amb as amb_law
from amb_plant_sim.closed_loop import build_closed_loop, build_plant
from amb_plant_sim.discretize import discretise
from amb_plant_sim.modal import natural_frequencies
from amb_plant_sim.pid import pid_frequency_response, pid_state_space


def test_pid_state_space_is_the_table_2_3_law(rig):
    ss = pid_state_space(rig.pid, rig.amb.Ki, n_axes=1)
    w = np.array([1.0, 10.0, 100.0, 1500.0, 1e4])
    tf = np.array(
        [(ss.C @ np.linalg.solve(1j * wk * np.eye(2) - ss.A, ss.B) + ss.D)[0, 0] for wk in w]
    )
    s = 1j * w
    # Table 2.3: 3 MN/m, 0.1 MN/(m s), 3 kN s/m (see rig.yaml), roll-off at 1500 rad/s
    law = 3.0e6 + 0.1e6 / s + 3.0e3 * s / (1 + s / 1500.0)
    np.testing.assert_allclose(-tf * 572.0, law, rtol=1e-12)
    np.testing.assert_allclose(pid_frequency_response(rig.pid, w), law, rtol=1e-12)


def test_table_2_2_geometry_gives_the_thesis_stiffness_and_gain(rig):
    """Section 2.3: eq. 2.39-2.40 with Table 2.2's geometry and 572 N/A give 2240 N/mm."""
    a = rig.amb
    mu0 = 4e-7 * math.pi
    k = mu0 * a.turns**2 * a.pole_area
    ib = 572.0 * a.nominal_air_gap**2 / (4 * k)
    assert 4 * k * ib**2 / a.nominal_air_gap**3 == pytest.approx(2240e3, rel=0.01)


@pytest.mark.parametrize("kz", [2240e3, (2156e3 + 1994e3) / 2])
def test_both_force_laws_have_the_rig_s_slopes(rig, kz):
    """The pair law (eq. 2.33) and the linear law have the same slopes at the origin: 572 N/A
    (section 2.3) and the rig's K_z, the computed 2240 N/mm or the mean of the two measured
    2156 and 1994 N/mm (figure 2.11)."""
    a = replace(rig.amb, Kz=kz)
    x = np.array([-1e-7, 1e-7])
    i = np.array([-1e-5, 1e-5])
    kz_pair = np.diff(amb_law.pair_force(a, np.zeros(2), x))[0] / 2e-7
    ki_pair = np.diff(amb_law.pair_force(a, i, np.zeros(2)))[0] / 2e-5
    assert ki_pair == pytest.approx(572.0, rel=1e-6)
    assert kz_pair == pytest.approx(kz, rel=1e-6)
    assert amb_law.linear_force(a, 1.0, 0.0) == pytest.approx(572.0)
    assert amb_law.linear_force(a, 0.0, 1.0) == pytest.approx(kz)


def test_the_force_slew_rate_is_the_coil_equation_at_table_2_2_s_peak_voltage(rig):
    """Eq. 2.42 (v = R i + L di/dt) at the peak current: (95.2 - 0.365 x 10) V over 0.0732 H,
    times 572 N/A (Table 2.2, section 2.3); the coil's exact current (closed form of the same
    equation) over one sample at 67 Hz x 32 reaches it to within R T / 2 L."""
    rate = rig.amb.force_slew_rate
    assert rate == pytest.approx(572.0 * (95.2 - 0.365 * 10.0) / 0.0732, rel=1e-12)
    t = 1.0 / (67.0 * 32)
    v, r, ell, i0 = 95.2, 0.365, 0.0732, 10.0
    rise = (v / r - i0) * (1.0 - math.exp(-r * t / ell))  # from 10 A with the full voltage
    assert 572.0 * rise == pytest.approx(rate * t, rel=r * t / ell)


def test_single_coil_left_attracts_by_its_bias_force(rig):
    a = rig.amb
    modes = np.array([amb_law.COIL_POSITIVE, amb_law.COIL_NEGATIVE, amb_law.LOST, 0])
    f = amb_law.amb_force(a, np.zeros(4), np.zeros(4), modes)
    # k (I_b / c_g)^2 with K_i = 4 k I_b / c_g^2 and K_z = 4 k I_b^2 / c_g^3 (eq. 2.39-2.40)
    f_bias = a.Kz * a.nominal_air_gap / 4
    np.testing.assert_allclose(f, [f_bias, -f_bias, 0.0, 0.0], rtol=1e-12)
    assert 500.0 < f_bias < 1000.0  # uncompensated pull of several hundred newtons


@pytest.mark.parametrize("speed_hz", np.arange(0.0, 101.0, 10.0))
def test_pid_closed_loop_stable_from_0_to_100_hz(rig, speed_hz):
    cl = build_closed_loop(rig, 2 * math.pi * speed_hz)
    assert np.max(np.linalg.eigvals(cl.A).real) < 0.0


@pytest.mark.parametrize("speed_hz,spr", [(5.0, 64), (11.0, 64), (67.0, 32), (100.0, 32)])
def test_sampled_closed_loop_stable(rig, speed_hz, spr):
    plant = build_plant(rig, 2 * math.pi * speed_hz)
    d = discretise(
        plant,
        pid_state_space(rig.pid, rig.amb.Ki),
        spr,
        rig.simulation.internal_rate_min,
        plant.position_rows([0]),
        4,
    )
    assert d.n_sub * spr * speed_hz >= 5000.0  # the PID runs at >= 5 kHz
    assert np.max(np.abs(np.linalg.eigvals(d.F))) < 1.0


def test_calibrated_frequencies_match_the_record_and_the_thesis(rig):
    rec = rig.calibration
    f = natural_frequencies(rig, 4)
    np.testing.assert_allclose(f, rec["achieved_hz"], rtol=2e-4)
    rel = np.asarray(rec["achieved_hz"]) / np.array([11.0, 18.0, 29.0, 67.0]) - 1.0
    np.testing.assert_allclose(rel, rec["relative_error"], atol=1e-4)
    assert np.max(np.abs(rel)) <= rec["max_relative_error"] + 1e-4
    assert rec["max_relative_error"] < 0.15  # the residual the calibration reached
    assert rec["stable"] is True


def test_calibrated_masses_and_moves_within_their_bounds(rig):
    """Section 2.2.4's stated masses (10 kg disks, 5 kg cores, a 50 kg shaft) and Table 2.1's
    geometry bound the masses; the moves stay within the bound the calibration record names."""
    for d in rig.disks:
        assert 10.0 <= d.mass <= d.geometric_mass + 1e-9
    for c in rig.amb_cores:
        assert 5.0 <= c.mass <= c.geometric_mass + 1e-9
    shaft_section = 7850.0 * math.pi * 0.025**2 * 2.0  # Table 2.1: 30.8 kg
    record = rig.calibration
    assert 0.0 <= rig.shaft.nonstructural_mass <= record["max_nonstructural_mass_kg"] + 1e-9
    assert shaft_section + record["max_nonstructural_mass_kg"] <= 50.0
    proposal = {"D1": 1.94, "D2": 1.28, "D3": 0.72, "D4": 0.06}
    for d in rig.disks:
        assert abs(d.z - proposal[d.tag]) <= record["max_shift_m"] + 1e-9
    # arrangement: D4 < AMB2 < S3 < D3 < D2 < S2 < AMB1 < D1 along z
    z = {d.tag: d.z for d in rig.disks}
    b1, b2 = (b.z for b in rig.bearings)
    s2, s3 = rig.sensor_planes[1].z, rig.sensor_planes[2].z
    chain = [z["D4"], b2, s3, z["D3"], z["D2"], s2, b1, z["D1"]]
    assert all(np.diff(chain) > 0)


def test_proportional_gain_must_exceed_the_negative_stiffness(rig):
    """Section 2.6 / figure 2.13: P-only control needs K_p above K_z (non-collocation)."""

    def unstable_real_poles(kp):
        g = PidGains(Kp=kp, KI=0.0, Kd=0.0, derivative_cutoff=1500.0)
        lam = np.linalg.eigvals(build_closed_loop(rig, 0.0, gains=g).A)
        # x/y double eigenvalues: rounding may split a real pair into a complex one with
        # |Im| ~ 1e-8 |lambda| (measured up to 2e-8); a vibration mode has |Im| ~ |lambda|
        return np.sum((lam.real > 1e-3) & (np.abs(lam.imag) < 1e-5 * np.abs(lam)))

    kz = rig.amb.Kz
    assert unstable_real_poles(0.0) > 0
    assert unstable_real_poles(0.99 * kz) > 0
    assert unstable_real_poles(1.01 * kz) > 0  # sensor 40 mm from the AMB: K_z is not enough
    assert unstable_real_poles(3.0e6) == 0


def test_calibration_record_round_trips_through_the_rig_file(rig, tmp_path):
    import dataclasses
    import shutil

    from amb_common.rig import load_rig
    from amb_plant_sim.calibrate import apply_parameters, parameters_of, write_calibration

    from .conftest import RIG_PATH

    path = tmp_path / "rig.yaml"
    shutil.copy(RIG_PATH, path)
    p = parameters_of(rig)
    p[0] -= 0.01  # move D1 by 10 mm, make the disks 11 kg, add 7.5 kg to the shaft
    p[8] = 11.0
    p[10] = 7.5
    moved = apply_parameters(rig, p)
    write_calibration(path, moved, {"targets_hz": [11.0], "note": "test"})
    write_calibration(path, moved, {"targets_hz": [11.0], "note": "test"})  # twice: no repeats
    back = load_rig(path)
    assert back.disks[0].z == pytest.approx(rig.disks[0].z - 0.01)
    assert all(d.mass == 11.0 for d in back.disks)
    assert back.shaft.nonstructural_mass == 7.5
    assert back.calibration == {"targets_hz": [11.0], "note": "test"}
    assert dataclasses.replace(back, calibration={}, source="") == dataclasses.replace(
        moved, calibration={}, source=""
    )
    assert path.read_text().count("(do not edit by hand)") == 1


def test_calibration_refuses_more_non_structural_mass_than_the_text_s_shaft(rig):
    from amb_plant_sim.calibrate import calibrate

    with pytest.raises(ValueError, match=r"expected 0 to 19\.17 kg"):
        calibrate(rig, max_nonstructural_mass=25.0)
    with pytest.raises(ValueError, match="expected 'least_squares' or 'minimax'"):
        calibrate(rig, objective="max")


@pytest.mark.parametrize(
    ("option", "value", "says"),
    [
        ("--critical-speeds", "11,x,29", "expected frequencies in Hz, comma separated"),
        ("--targets", "11,-18", "every frequency must be > 0 Hz"),
    ],
)
def test_calibrate_refuses_a_frequency_list_it_cannot_read(capsys, option, value, says):
    from amb_plant_sim.calibrate import main

    with pytest.raises(SystemExit) as exit_:
        main([option, value])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert says in err and option in err, err


def test_calibration_errors_put_the_critical_speeds_after_the_natural_frequencies(rig):
    from amb_plant_sim.calibrate import frequency_errors
    from amb_plant_sim.modal import critical_speeds, natural_frequencies

    natural = natural_frequencies(rig, 4)
    critical = critical_speeds(rig, 3)
    rel, achieved, stable = frequency_errors(rig, (11.0, 18.0, 29.0, 67.0), (11.0, 18.0, 29.0))
    assert stable
    np.testing.assert_allclose(achieved, natural + critical, rtol=1e-12)
    want = np.r_[natural, critical] / np.array([11.0, 18.0, 29.0, 67.0, 11.0, 18.0, 29.0]) - 1
    np.testing.assert_allclose(rel, want, rtol=1e-12)
    # inside a fit the critical speeds are iterated to 1 mHz only
    _rel, fit, _stable = frequency_errors(rig, (11.0,), (11.0, 18.0), fit=True)
    np.testing.assert_allclose(fit[1:], critical[:2], atol=2e-3)
