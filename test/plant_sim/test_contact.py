"""
Contact model (eq. 5.5): Hertzian impact against the closed-form solution, energy
dissipation by contact damping, friction against slip, and bounded penetration in the rig.
"""

import dataclasses
import math

import numpy as np
import pytest
import scipy.integrate

from amb_plant_sim.contact import contact_forces
from amb_plant_sim.events import misalignment_offset
from amb_plant_sim.scenario import load_scenario
from amb_plant_sim.simulator import PlantSimulator

from .conftest import RIG_PATH

SCENARIOS = RIG_PATH.parent / "scenarios"


def _impact(params, mass, v0, clearance=1e-4):
    """A point mass moving radially along +x into the bearing; returns (max delta, v_out)."""

    def rhs(t, s):
        f = contact_forces(
            np.array([[s[0], 0.0]]),
            np.array([[s[1], 0.0]]),
            np.zeros((1, 2)),
            np.array([clearance]),
            0.0,
            params,
        ).force[0, 0]
        return [s[1], f / mass]

    def leave(t, s):
        return s[0] - (clearance - 1e-6)

    leave.terminal, leave.direction = True, -1
    sol = scipy.integrate.solve_ivp(
        rhs,
        (0, 0.05),
        [clearance, v0],
        method="DOP853",
        rtol=1e-11,
        atol=1e-15,
        events=leave,
        max_step=1e-6,
    )
    return sol.y[0].max() - clearance, sol.y[1, -1]


@pytest.mark.slow
def test_hertz_impact_matches_closed_form_and_conserves_energy(rig):
    params = dataclasses.replace(rig.contact, damping=0.0, friction=0.0, model="hertz")
    m, v0 = 20.0, 0.05
    delta_max, v_out = _impact(params, m, v0)
    # energy: m v0^2 / 2 = 2/5 k delta^(5/2)
    expected = (5 * m * v0**2 / (4 * params.hertz_stiffness)) ** 0.4
    assert delta_max == pytest.approx(expected, rel=1e-4)
    assert v_out == pytest.approx(-v0, rel=1e-3)  # elastic: no energy lost


@pytest.mark.slow
def test_penalty_impact_matches_closed_form(rig):
    params = dataclasses.replace(rig.contact, damping=0.0, friction=0.0, model="penalty")
    m, v0 = 20.0, 0.05
    delta_max, _ = _impact(params, m, v0)
    assert delta_max == pytest.approx(v0 * math.sqrt(m / params.penalty_stiffness), rel=1e-4)


@pytest.mark.slow
def test_contact_damping_dissipates_energy(rig):
    params = dataclasses.replace(rig.contact, friction=0.0)
    assert params.damping > 0.0
    m, v0 = 20.0, 0.05
    _, v_out = _impact(params, m, v0)
    restitution = -v_out / v0
    assert 0.0 < restitution < 0.999
    # more damping, more loss
    _, v_out2 = _impact(dataclasses.replace(params, damping=4 * params.damping), m, v0)
    assert -v_out2 / v0 < restitution


def test_friction_opposes_slip_and_follows_coulomb(rig):
    params = rig.contact
    rng = np.random.default_rng(5)
    ang = rng.uniform(0, 2 * np.pi, 50)
    n = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    pos = n * (750e-6 + rng.uniform(1e-6, 50e-6, 50))[:, None]
    vel = rng.normal(0, 0.05, (50, 2))
    for omega in (-300.0, 0.0, 300.0):
        res = contact_forces(pos, vel, np.zeros((50, 2)), np.full(50, 750e-6), omega, params)
        t = np.stack([-n[:, 1], n[:, 0]], axis=1)
        slip = np.sum(vel * t, axis=1) + omega * params.rotor_radius
        f_t = np.sum(res.force * t, axis=1)
        f_n = -np.sum(res.force * n, axis=1)
        assert np.all(f_n >= 0.0)
        moving = (np.abs(slip) > 1e-2) & (f_n > 0.0)
        assert np.all(f_t[moving] * slip[moving] < 0.0)  # friction opposes the slip
        np.testing.assert_allclose(
            np.abs(f_t[moving]), params.friction * f_n[moving], rtol=1e-3
        )  # |f_t| = mu f_c once slipping (tanh saturated)
    free = contact_forces(pos * 0.5, vel, np.zeros((50, 2)), np.full(50, 750e-6), 300.0, params)
    assert not np.any(free.in_contact) and np.all(free.force == 0.0)


def test_misaligned_auxiliary_bearing_contact_in_the_rig(rig):
    sc = load_scenario(SCENARIOS / "contact_misalignment_second_bending.yaml", rig)
    sim = PlantSimulator(rig, sc, sc.samples_per_rev)
    blk = sim.advance(int(0.9 * sim.fs))
    k = [c.tag for c in rig.clearance_bearings].index("AB1")
    touched = blk.truth["contact"][:, k]
    assert touched.any()  # the misalignment brings AB1 into contact
    assert not blk.truth["contact"][blk.time < 0.5].any()  # not before the misalignment
    # penetration bounded by the Hertzian penetration of the largest recorded force
    ev = sc.events[1]
    centre = np.array([misalignment_offset(ev, t) for t in blk.time])
    r = np.linalg.norm(blk.truth["journal_displacement"][:, k] - centre, axis=1)
    f_max = blk.truth["contact_force"][:, k].max()
    delta_bound = (f_max / rig.contact.hertz_stiffness) ** (2 / 3)
    assert f_max > 1.0
    assert np.max(r) - 750e-6 < 1.5 * delta_bound + 5e-6
