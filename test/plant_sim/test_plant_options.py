"""Selectable plant options: coil dynamics (eq. 2.42), nonlinear AMB law (eq. 2.33), base motion."""

import dataclasses
import math

import numpy as np
import pytest

from amb_plant_sim.closed_loop import build_closed_loop
from amb_plant_sim.rotor import build_rotor
from amb_plant_sim.scenario import scenario_from_dict
from amb_plant_sim.simulator import PlantSimulator

UNB = {"kind": "unbalance", "disk": "D1", "me": 0.5e-3, "angle": 0.0}


def _orbit(rig, events, n_rev=60, f_hz=20.0, spr=32):
    sc = scenario_from_dict({"speed": {"hz": f_hz}, "duration": 10.0, "events": events}, rig)
    blk = PlantSimulator(rig, sc, spr).advance(n_rev * spr)
    return blk, np.abs(blk.truth["true_displacement"][-10 * spr :]).max(axis=0)


def _with_amb(rig, **kw):
    return dataclasses.replace(rig, amb=dataclasses.replace(rig.amb, **kw))


def test_coil_amplifier_is_stable_and_tends_to_the_ideal_one(rig):
    coil = _with_amb(rig, amplifier="coil")
    cl = build_closed_loop(coil, 2 * math.pi * 50.0)
    assert np.max(np.linalg.eigvals(cl.A).real) < 0.0
    assert cl.A.shape[0] == build_closed_loop(rig, 0.0).A.shape[0] + 4  # four coil currents
    _, ideal = _orbit(rig, [UNB])
    _, fast = _orbit(_with_amb(rig, amplifier="coil", amplifier_bandwidth=2.0e5), [UNB])
    np.testing.assert_allclose(fast, ideal, rtol=2e-2)
    blk, slow = _orbit(coil, [UNB])  # the 1 kHz current loop lags: the orbit changes
    assert np.max(np.abs(slow / ideal - 1.0)) > 1e-3
    # the published current is the coil current, which follows the PID demand
    assert np.abs(blk.current).max() > 0.0


def test_nonlinear_law_matches_the_linear_one_for_small_orbits(rig):
    _, lin = _orbit(rig, [UNB])
    blk, non = _orbit(_with_amb(rig, law="nonlinear"), [UNB])
    assert np.all(blk.truth["step_by_step"])
    assert lin.max() < 0.1 * rig.amb.nominal_air_gap  # small compared with the air gap
    np.testing.assert_allclose(non, lin, rtol=2e-2)


def test_base_acceleration_is_carried_by_the_bearings(rig):
    a = 2.0  # m/s^2 along x from t = 0.1 s (eq. 3.6: force -M y'')
    ev = {"kind": "base_motion", "time": 0.1, "direction": "x", "amplitude": a}
    blk, _ = _orbit(rig, [ev], n_rev=40, f_hz=25.0, spr=16)
    rot = build_rotor(rig)
    r = rot.rigid_modes()[:, 0]
    mass = r @ rot.M @ r
    f = blk.truth["amb_force"]
    # quasi-static after the transient: the AMBs push the rotor with m a (Newton)
    np.testing.assert_allclose(f[-20:, 0] + f[-20:, 2], mass * a, rtol=1e-2)
    np.testing.assert_allclose(f[-20:, 1] + f[-20:, 3], 0.0, atol=1e-3 * mass * a)
    assert np.all(np.abs(f[blk.time < 0.1]) < 1e-9)
    assert mass == pytest.approx(
        sum(b.mass for b in rig.rigid_bodies)
        + 7850 * math.pi * 0.025**2 * 2
        + rig.shaft.nonstructural_mass
    )
