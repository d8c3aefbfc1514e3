"""
Assembled rotor matrices (eq. 2.14): symmetry, definiteness, skewness, and mass properties
against a hand sum of the Table 2.1 parts.
"""

import math
from dataclasses import replace

import numpy as np
import pytest
import yaml

from amb_common.rig import rig_from_dict
from amb_plant_sim.closed_loop import build_plant
from amb_plant_sim.modal import modes_from_matrix
from amb_plant_sim.rotor import build_rotor

from .conftest import RIG_PATH


@pytest.fixture(scope="module")
def table21_rig():
    """The rig with the Table 2.1 geometric masses (no calibrated mass override)."""
    data = yaml.safe_load(RIG_PATH.read_text())
    for key in ("disks", "amb_cores", "collars"):
        for body in data[key]:
            body.pop("mass", None)
    data["shaft"].pop("nonstructural_mass", None)
    return rig_from_dict(data)


def test_symmetry_and_definiteness(rig):
    m = build_rotor(rig)
    np.testing.assert_allclose(m.M, m.M.T, atol=1e-12 * np.abs(m.M).max())
    np.testing.assert_allclose(m.K, m.K.T, atol=1e-12 * np.abs(m.K).max())
    np.testing.assert_allclose(m.G, -m.G.T, atol=0)
    np.testing.assert_allclose(m.Kc, -m.Kc.T, atol=0)
    assert np.linalg.eigvalsh(m.M).min() > 0.0
    k_eig = np.linalg.eigvalsh(m.K)
    # four rigid-body modes (2 translations, 2 tilts) at zero, the rest positive
    assert np.all(np.abs(k_eig[:4]) < 1e-9 * k_eig[-1])
    assert k_eig[4] > 1e-6 * k_eig[-1]
    # rigid-body motion stores no strain energy
    np.testing.assert_allclose(m.K @ m.rigid_modes(), 0.0, atol=1e-6 * np.abs(m.K).max())


def _hand_sums():
    """Table 2.1 / section 2.2.4 parts summed by hand: mass, I_p, I_d about the drive end."""
    rho_s, rho_c, L, r = 7850.0, 6000.0, 2.0, 0.025
    layout = yaml.safe_load(RIG_PATH.read_text())
    parts = []  # (mass, Ip, Id about own centre, z)
    for d in layout["disks"]:  # 125/25 mm, 35 mm wide, steel
        m = rho_s * math.pi * (0.125**2 - 0.025**2) * 0.035
        parts.append(
            (
                m,
                m * (0.125**2 + 0.025**2) / 2,
                m * (3 * (0.125**2 + 0.025**2) + 0.035**2) / 12,
                d["z"],
            )
        )
    for c in layout["amb_cores"]:  # 89/25 mm, 60 mm wide, 6000 kg/m^3
        m = rho_c * math.pi * (0.089**2 - 0.025**2) * 0.060
        parts.append(
            (
                m,
                m * (0.089**2 + 0.025**2) / 2,
                m * (3 * (0.089**2 + 0.025**2) + 0.060**2) / 12,
                c["z"],
            )
        )
    for c in layout["collars"]:  # assumed 35/25 mm, 20 mm (rig.yaml says so)
        m = rho_s * math.pi * (0.035**2 - 0.025**2) * 0.020
        parts.append(
            (
                m,
                m * (0.035**2 + 0.025**2) / 2,
                m * (3 * (0.035**2 + 0.025**2) + 0.020**2) / 12,
                c["z"],
            )
        )
    m_shaft = rho_s * math.pi * r**2 * L
    mass = m_shaft + sum(p[0] for p in parts)
    ip = m_shaft * r**2 / 2 + sum(p[1] for p in parts)
    # slender-rod + disk-like section term: m (3 r^2 + L^2)/12 about the centre, shifted to z=0
    id0 = m_shaft * (3 * r**2 + L**2) / 12 + m_shaft * (L / 2) ** 2
    id0 += sum(p[2] + p[0] * p[3] ** 2 for p in parts)
    return mass, ip, id0


def test_mass_and_inertia_vs_hand_sum(table21_rig):
    m = build_rotor(table21_rig)
    R = m.rigid_modes()
    mass, ip, id0 = _hand_sums()
    assert mass == pytest.approx(50.0 + 4 * 10 + 2 * 5, rel=0.25)  # thesis: 50 + 4x10 + 2x5 kg
    assert R[:, 0] @ m.M @ R[:, 0] == pytest.approx(mass, rel=1e-12)
    assert R[:, 1] @ m.M @ R[:, 1] == pytest.approx(mass, rel=1e-12)
    assert R[:, 2] @ m.M @ R[:, 2] == pytest.approx(id0, rel=1e-9)
    assert R[:, 3] @ m.M @ R[:, 3] == pytest.approx(id0, rel=1e-9)
    # polar inertia: the gyroscopic work of a unit tilt pair
    assert R[:, 3] @ m.G @ R[:, 2] == pytest.approx(ip, rel=1e-9)


def test_nonstructural_mass_is_inertia_of_a_uniform_rod_without_stiffness(table21_rig):
    """Mass m spread uniformly over the 2 m, 25 mm radius shaft adds m to the mass,
    m (L^2/3 + r^2/4) to I_d about the drive end (a thin rod plus its sections' own diametral
    inertia), m r^2/2 to I_p, and nothing to the stiffness."""
    m_ns, L, r = 18.5, 2.0, 0.025
    plain = build_rotor(table21_rig)
    heavy = build_rotor(
        replace(table21_rig, shaft=replace(table21_rig.shaft, nonstructural_mass=m_ns))
    )
    R = plain.rigid_modes()
    dM = heavy.M - plain.M
    assert R[:, 0] @ dM @ R[:, 0] == pytest.approx(m_ns, rel=1e-9)
    assert R[:, 2] @ dM @ R[:, 2] == pytest.approx(m_ns * (L**2 / 3 + r**2 / 4), rel=1e-9)
    assert R[:, 3] @ (heavy.G - plain.G) @ R[:, 2] == pytest.approx(m_ns * r**2 / 2, rel=1e-9)
    np.testing.assert_array_equal(heavy.K, plain.K)


def test_rigid_body_nutation_frequency(rig):
    """A free spinning rigid body nutates forward at Omega I_p / I_d (Euler's equations)."""
    m = build_rotor(rig)
    R = m.rigid_modes()
    mass = R[:, 0] @ m.M @ R[:, 0]
    z_cm = (R[:, 0] @ m.M @ R[:, 2]) / mass
    id_cm = R[:, 2] @ m.M @ R[:, 2] - mass * z_cm**2
    ip = R[:, 3] @ m.G @ R[:, 2]
    omega = 2 * math.pi * 100.0
    plant = build_plant(rig, omega, amb_stiffness=False, amplifier="ideal")
    modes = modes_from_matrix(plant.A, m.n_dof, min_frequency_hz=1e-3, max_frequency_hz=10.0)
    expected = omega * ip / id_cm / (2 * math.pi)
    assert expected > 0.5  # a real effect, ~1 Hz
    fwd = [md for md in modes if md.whirl == "forward"]
    assert len(fwd) == 1
    # flexibility of the shaft (first bending mode ~30 Hz) shifts it only slightly
    assert fwd[0].frequency_hz == pytest.approx(expected, rel=0.02)


def test_gyroscopic_splitting_forward_up_backward_down(rig):
    plant0 = build_plant(rig, 0.0, amb_stiffness=False, amplifier="ideal")
    plant1 = build_plant(rig, 2 * math.pi * 100.0, amb_stiffness=False, amplifier="ideal")
    n = plant0.rotor.n_dof
    f0 = modes_from_matrix(plant0.A, n, min_frequency_hz=5.0)[0].frequency_hz
    m1 = modes_from_matrix(plant1.A, n, min_frequency_hz=5.0)[:2]
    whirls = {md.whirl: md.frequency_hz for md in m1}
    assert whirls["backward"] < f0 < whirls["forward"]
