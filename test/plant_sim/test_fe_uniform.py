"""
Uniform shafts against closed-form beam theory.

References (outside the code under test):
- Euler-Bernoulli free-free beam: beta_n L = 4.730041, 7.853205, 10.995608, 14.137165
  (roots of cos(bL) cosh(bL) = 1), omega_n = (beta_n L)^2 sqrt(E I / (rho A L^4)).
- Timoshenko simply supported beam: for wavenumber k = n pi / L the frequencies solve
  rho^2 I/(kappa G) w^4 - (rho A + rho I k^2 + rho E I k^2/(kappa G)) w^2 + E I k^4 = 0
  (Timoshenko 1921; e.g. Han, Benaroya & Wei 1999, J. Sound Vib. 225, eq. for the S-S case).
"""

import itertools
import math

import numpy as np
import pytest
import scipy.linalg
import scipy.optimize

from amb_common.rig import Material, ShaftData
from amb_plant_sim.elements import shear_coefficient
from amb_plant_sim.rotor import assemble

STEEL = Material(rho=7850.0, E=2.1e11, poisson=0.3)


def _free_free_hz(length, radius, elements, shear, rotary):
    shaft = ShaftData(length, radius, 0.0, STEEL, elements, shear=shear, rotary_inertia=rotary)
    m = assemble(np.linspace(0.0, length, elements + 1), shaft)
    # x plane only: DOFs x and beta of each node (the y plane is identical)
    idx = np.sort(np.r_[np.arange(0, m.n_dof, 4), np.arange(3, m.n_dof, 4)])
    w2 = scipy.linalg.eigh(m.K[np.ix_(idx, idx)], m.M[np.ix_(idx, idx)], eigvals_only=True)
    return np.sqrt(np.abs(w2[2:6])) / (2 * math.pi)  # drop the two rigid-body modes


def _euler_bernoulli_free_free_hz(length, radius, n=4):
    roots = [
        scipy.optimize.brentq(lambda b: math.cos(b) * math.cosh(b) - 1.0, lo, lo + 2.5)
        for lo in (4.0, 7.0, 10.5, 13.5)
    ][:n]
    area, inertia = math.pi * radius**2, math.pi * radius**4 / 4
    c = math.sqrt(STEEL.E * inertia / (STEEL.rho * area * length**4))
    return np.array(roots) ** 2 * c / (2 * math.pi)


def test_beam_roots_are_the_textbook_values():
    ref = _euler_bernoulli_free_free_hz(1.0, 0.01)
    area, inertia = math.pi * 1e-4, math.pi * 1e-8 / 4
    c = math.sqrt(STEEL.E * inertia / (STEEL.rho * area)) / (2 * math.pi)
    np.testing.assert_allclose(
        ref / c, np.array([4.730041, 7.853205, 10.995608, 14.137165]) ** 2, rtol=1e-6
    )


@pytest.mark.parametrize("length,radius", [(2.0, 0.025), (1.0, 0.01)])
def test_free_free_euler_bernoulli_within_half_percent(length, radius):
    fe = _free_free_hz(length, radius, 40, shear=False, rotary=False)
    ref = _euler_bernoulli_free_free_hz(length, radius)
    np.testing.assert_allclose(fe, ref, rtol=5e-3)
    # cubic Hermite elements converge fast: 40 elements are far better than 0.5 %
    np.testing.assert_allclose(fe, ref, rtol=3e-5)


def test_slender_timoshenko_shaft_approaches_euler_bernoulli():
    # L/D = 100: shear and rotary inertia lower the first four modes by under 0.5 %, not 0
    fe = _free_free_hz(2.0, 0.01, 40, shear=True, rotary=True)
    ref = _euler_bernoulli_free_free_hz(2.0, 0.01)
    np.testing.assert_allclose(fe, ref, rtol=5e-3)
    assert np.all(fe < ref)  # shear and rotary inertia can only soften a beam


def test_convergence_with_element_count():
    ref = _euler_bernoulli_free_free_hz(2.0, 0.025)
    errors = [
        np.max(np.abs(_free_free_hz(2.0, 0.025, n, False, False) / ref - 1.0))
        for n in (3, 6, 12, 24)
    ]
    assert all(b < a for a, b in itertools.pairwise(errors))
    assert errors[-1] < 1e-4
    # Hermite cubics: frequency error ~ h^4, so halving h gains about 16 (at least 8 here)
    assert errors[2] / errors[3] > 8.0


def _pinned_pinned_hz(length, radius, elements):
    shaft = ShaftData(length, radius, 0.0, STEEL, elements, shear=True, rotary_inertia=True)
    m = assemble(np.linspace(0.0, length, elements + 1), shaft)
    idx = np.sort(np.r_[np.arange(0, m.n_dof, 4), np.arange(3, m.n_dof, 4)])
    idx = idx[(idx != 0) & (idx != m.n_dof - 4)]  # pin x at both ends
    w2 = scipy.linalg.eigh(m.K[np.ix_(idx, idx)], m.M[np.ix_(idx, idx)], eigvals_only=True)
    return np.sqrt(w2[:3]) / (2 * math.pi)


def _timoshenko_ss_hz(length, radius, n_modes=3):
    area, inertia = math.pi * radius**2, math.pi * radius**4 / 4
    kappa = 6 * (1 + STEEL.poisson) / (7 + 6 * STEEL.poisson)  # Cowper, solid circle
    Gs = STEEL.E / (2 * (1 + STEEL.poisson))
    rho, E = STEEL.rho, STEEL.E
    out = []
    for n in range(1, n_modes + 1):
        k = n * math.pi / length
        a = rho**2 * inertia / (kappa * Gs)
        b = -(rho * area + rho * inertia * k**2 + rho * E * inertia * k**2 / (kappa * Gs))
        c = E * inertia * k**4
        w2 = (-b - math.sqrt(b * b - 4 * a * c)) / (2 * a)  # lower (bending) branch
        out.append(math.sqrt(w2) / (2 * math.pi))
    return np.array(out)


def test_cowper_coefficient_solid_circle():
    assert shear_coefficient(0.3, 0.0, 1.0) == pytest.approx(6 * 1.3 / 8.8, rel=1e-12)


def test_thick_timoshenko_shaft_pinned_pinned_within_half_percent():
    # L/D = 3: shear and rotary inertia lower the 3rd mode by tens of percent vs Euler-Bernoulli
    length, radius = 0.3, 0.05
    fe = _pinned_pinned_hz(length, radius, 60)
    ref = _timoshenko_ss_hz(length, radius)
    np.testing.assert_allclose(fe, ref, rtol=5e-3)
    eb = (
        np.array([1, 4, 9])
        * (math.pi / length) ** 2
        * math.sqrt(STEEL.E * radius**2 / 4 / STEEL.rho)
        / (2 * math.pi)
    )
    assert fe[2] < 0.8 * eb[2]  # the effect tested is large, not a rounding
