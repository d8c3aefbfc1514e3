"""
Analyses (figures 2.6, 2.7, 2.13, 2.16, sensitivity/ISO 14839-3), the rotating-frame model
(eq. 2.22-2.30) and the amb-modal command line.
"""

import json
import math

import numpy as np
import pytest

from amb_common.errors import RigError
from amb_plant_sim import analysis
from amb_plant_sim.closed_loop import build_closed_loop, build_plant
from amb_plant_sim.modal import distinct_modes, free_free_modes
from amb_plant_sim.modal_cli import main
from amb_plant_sim.pid import pid_frequency_response
from amb_plant_sim.rotating_frame import rotation_matrix, to_rotating_frame
from amb_plant_sim.rotor import build_rotor


def _direct_input_sensitivity(rig, f_hz: float) -> np.ndarray:
    """diag (I + K P)^-1 at one frequency from the open-loop plant and the Table 2.3 law."""
    plant = build_plant(rig, 0.0)  # open loop: current (A) -> inner sensors (m)
    w = 2 * math.pi * f_hz
    P = plant.C_in @ np.linalg.solve(1j * w * np.eye(plant.n_states) - plant.A, plant.B_i)
    K = pid_frequency_response(rig.pid, np.array([w]))[0] / rig.amb.Ki  # A per m
    return np.diag(np.linalg.inv(np.eye(4) + K * P))


def test_sensitivity_equals_the_mimo_input_sensitivity(rig):
    """G_s at axis a = [(I + K P)^-1]_aa from the open-loop plant and the Table 2.3 law."""
    f = np.array([2.0, 9.5, 17.0, 50.0, 300.0])
    S = analysis.sensitivity(rig, f)
    for k, fk in enumerate(f):
        # analysis works through the eigenvectors V of A: cond(V) ~ 1e8 gives ~2e-8 relative
        # rounding error on another LAPACK (measured 4e-10 here); 1e-6 keeps 50x above it
        np.testing.assert_allclose(S[k], _direct_input_sensitivity(rig, fk), rtol=1e-6)


def test_iso_zones():
    assert [analysis.iso_zone(v) for v in (1.2, 2.99, 3.0, 3.99, 4.0, 4.99, 5.0, 9.0)] == [
        "A",
        "A",
        "B",
        "B",
        "C",
        "C",
        "D",
        "D",
    ]


def test_sensitivity_peaks_of_the_rig(rig):
    peaks = analysis.sensitivity_peaks(rig)
    assert [p.axis for p in peaks] == ["b1x", "b1y", "b2x", "b2y"]
    modes = np.asarray(rig.calibration["achieved_hz"])
    for a, p in enumerate(peaks):
        assert p.peak > 1.0 and p.zone == analysis.iso_zone(p.peak)
        assert p.peak_db == pytest.approx(20 * math.log10(p.peak))
        # the peak is a resonance of the closed loop: at one of its lightly damped modes (the
        # damping shifts the peak from the natural frequency by a few per cent)
        assert np.min(np.abs(p.frequency_hz / modes - 1.0)) < 0.05
        # and a maximum of the direct solve: its value there, above its value 2 % either side
        at = abs(_direct_input_sensitivity(rig, p.frequency_hz)[a])
        assert at == pytest.approx(p.peak, rel=1e-6)
        for side in (0.98, 1.02):
            assert abs(_direct_input_sensitivity(rig, side * p.frequency_hz)[a]) < p.peak


def test_singular_values_equal_a_direct_solve(rig):
    f = np.array([5.0, 16.0, 80.0])
    sv = analysis.singular_values(rig, f)
    cl = build_closed_loop(rig, 0.0)
    C = cl.output(cl.plant.C_s)
    for k, fk in enumerate(f):
        G = C @ np.linalg.solve(2j * math.pi * fk * np.eye(cl.A.shape[0]) - cl.A, cl.B_u)
        # eigenvector route, cond(V) ~ 1e8: see the sensitivity test
        np.testing.assert_allclose(sv[k], np.linalg.svd(G, compute_uv=False), rtol=1e-6)
    assert np.all(np.diff(sv, axis=1) <= 0)  # ordered
    # at DC the integrators cancel a static AMB force where it acts: no static compliance
    G0 = C @ np.linalg.solve(-cl.A, cl.B_u)
    assert np.abs(G0).max() < 1e-12 * sv[0, 0]


def test_frequencies_converge_with_elements(rig):
    counts = [9, 11, 14, 20, 30]
    fr = analysis.frequencies_vs_elements(rig, counts)
    change = np.abs(np.diff(fr, axis=0)) / fr[1:]
    assert change[-1].max() < 2e-3  # converged (figure 2.6)
    ref = [m.frequency_hz for m in distinct_modes(free_free_modes(rig, 0.0, build_rotor(rig, 14)))]
    np.testing.assert_allclose(fr[2], ref[:4], rtol=1e-12)


def test_frequencies_vs_gain(rig):
    kz = rig.amb.Kz
    fr = analysis.frequencies_vs_gain(rig, np.array([0.0, 0.9 * kz, 3.0e6]))
    assert np.all(fr[0, :2] == 0.0) and np.all(fr[1, :2] == 0.0)  # figure 2.13: 0 Hz
    assert np.all(fr[2] > 1.0)
    assert np.all(np.diff(fr[2]) > 0)


def test_campbell_splits_into_forward_and_backward(rig):
    modes = analysis.campbell(rig, np.array([0.0, 80.0]), max_frequency_hz=100.0)
    assert all(m.whirl == "planar" for m in modes[0])
    whirls = {m.whirl for m in modes[1]}
    assert whirls == {"forward", "backward"}


def test_rotating_frame_steady_unbalance_is_static(rig):
    """A synchronous force is constant in the rotating frame: K_r r = f gives the orbit."""
    rot = build_rotor(rig)
    omega = 2 * math.pi * 25.0
    plant_K = rot.stiffness(omega) + 2.0e6 * sum(
        np.outer(e, e) for e in rot.translation_matrix([rot.node_at(b.z) for b in rig.bearings])
    )  # isotropic springs 2 MN/m at the bearings
    D = omega * rot.G + rot.damping() + 1e-4 * plant_K
    f = np.zeros(rot.n_dof, dtype=complex)
    node = rot.node_at(rig.disks[0].z)
    f[4 * node], f[4 * node + 1] = 100.0, -100.0j  # 100 N forward rotating at omega
    X = np.linalg.solve(-(omega**2) * rot.M + 1j * omega * D + plant_K, f)
    rf = to_rotating_frame(rot.M, D, plant_K, omega)
    for t in (0.0, 0.013, 0.031):
        T = rotation_matrix(rot.n_dof, omega * t)
        f_rot = T.T @ (f * np.exp(1j * omega * t)).real
        np.testing.assert_allclose(f_rot, f.real, atol=1e-9)  # constant in the frame (5.2)
        r = np.linalg.solve(rf.K, f_rot)  # steady state: r' = r'' = 0
        np.testing.assert_allclose(
            T @ r, (X * np.exp(1j * omega * t)).real, atol=1e-8 * np.abs(X).max()
        )


def test_rotating_frame_refuses_anisotropic_supports(rig):
    rot = build_rotor(rig)
    K = rot.K.copy()
    K[0, 0] += 1e6  # x-only spring
    with pytest.raises(RigError, match="not isotropic"):
        to_rotating_frame(rot.M, rot.G, K, 10.0)


def test_cli_json(capsys):
    assert main(["--json", "--speeds-hz", "0,50", "--modes", "4"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["model"] == "pid_closed_loop" and out["elements"] == 14
    assert [s["speed_hz"] for s in out["speeds"]] == [0.0, 50.0]
    f0 = [m["frequency_hz"] for m in out["speeds"][0]["modes"]]
    np.testing.assert_allclose(f0, out["calibration"]["achieved_hz"], rtol=1e-3)
    assert all(0 < m["damping_ratio"] < 1 for m in out["speeds"][1]["modes"])
    assert {p["zone"] for p in out["sensitivity"]} <= {"A", "B", "C", "D"}
    assert len(out["critical_speeds_hz"]) == 4


@pytest.mark.slow
def test_cli_free_free_and_plots(tmp_path, capsys):
    assert main(["--free-free", "--json", "--plot-dir", str(tmp_path), "--elements", "12"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["model"] == "free_free" and out["elements"] == 12
    assert 20.0 < out["speeds"][0]["modes"][0]["frequency_hz"] < 40.0
    names = {p.split("/")[-1] for p in out["plots"]}
    assert names == {
        "campbell.png",
        "elements.png",
        "gain.png",
        "singular_values.png",
        "modes_free_free.png",
        "modes_pid.png",
        "sensitivity.png",
    }
    for p in out["plots"]:
        with open(p, "rb") as fh:
            assert fh.read(8) == b"\x89PNG\r\n\x1a\n"


def test_cli_text_and_errors(capsys):
    assert main(["--speeds-hz", "10"]) == 0
    text = capsys.readouterr().out
    assert "speed 10.00 Hz" in text and "ISO 14839-3 zone" in text
    assert main(["--elements", "4"]) == 2
    assert "elements" in capsys.readouterr().err
