"""
The rolling auxiliary bearings' inner races (``contact.race_step``): spin-up against the
closed form, run-down, rolling in the simulated rig, and what the free race changes for a
diverging controller at full force (dry friction against a race held at rest feeds whirl).
"""

import dataclasses

import numpy as np
import pytest

from amb_plant_sim.contact import race_step
from amb_plant_sim.scenario import load_scenario
from amb_plant_sim.simulator import PlantSimulator

from .conftest import RIG_PATH

SCENARIOS = RIG_PATH.parent / "scenarios"


def test_race_spins_up_at_constant_friction_torque_and_then_rolls(rig):
    # J w' = -f_t R_r with f_t = -10 N on the rotor: w(t) = 10 R_r t / J until w = rolling
    params = dataclasses.replace(rig.contact, race_inertia=1e-4, race_drag=0.0)
    r_r, h, roll = np.array([0.02575]), 1e-5, np.array([195.0])
    alpha = 10.0 * r_r[0] / params.race_inertia  # rad/s^2
    w = np.zeros(1)
    trace = []
    for _ in range(10_000):
        w = race_step(w, np.array([-10.0]), roll, r_r, h, params)
        trace.append(w[0])
    trace = np.array(trace)
    n_roll = int(np.ceil(roll[0] / (alpha * h)))  # the step in which the race reaches rolling
    t = h * np.arange(1, n_roll)
    np.testing.assert_allclose(trace[: n_roll - 1], alpha * t, rtol=1e-9)
    assert np.all(trace[n_roll - 1 :] == roll[0])  # it stops at rolling, it does not overshoot
    # no friction at rolling: the race stays there (its drag is zero here)
    w = race_step(np.array(roll), np.array([0.0]), roll, r_r, h, params)
    assert w[0] == roll[0]


def test_race_runs_down_with_its_drag_time_constant(rig):
    params = dataclasses.replace(rig.contact, race_inertia=1e-4, race_drag=1e-5)  # J/c = 10 s
    w = np.array([200.0])
    h = 1e-4
    for _ in range(10_000):  # 1 s out of contact
        w = race_step(w, np.array([0.0]), np.array([0.0]), np.array([0.02575]), h, params)
    # implicit Euler on w' = -w/10: (1 + h/10)^-N = exp(-0.1 + N (h/10)^2 / 2 + ...), a
    # relative error of N (h/10)^2 / 2 = 5e-7; twice that as the tolerance
    np.testing.assert_allclose(w[0], 200.0 * np.exp(-0.1), rtol=1e-6)


def _pressed(rig, tmp_path):
    """A journal pressed onto AB1 by a 3 kN static force at 20 Hz (no unbalance)."""
    path = tmp_path / "pressed.yaml"
    path.write_text(
        "name: pressed\nspeed: {hz: 20.0}\nduration: 1.0\nsamples_per_rev: 32\n"
        "events:\n  - {kind: step_force, time: 0.05, bearing: 1, fx: 3000.0}\n"
    )
    return load_scenario(path, rig)


def test_journal_pressed_on_an_auxiliary_bearing_rolls_its_race(rig, tmp_path):
    sc = _pressed(rig, tmp_path)
    sim = PlantSimulator(rig, sc, sc.samples_per_rev)
    blk = sim.advance(int(0.4 * sim.fs))
    tags = [c.tag for c in rig.clearance_bearings]
    k = tags.index("AB1")
    assert blk.truth["contact"][-32:, k].all()  # held on AB1 for the last revolution
    # rolling: race surface speed = journal surface speed (the journal rests, no whirl)
    r_r = rig.contact.rotor_radius + rig.clearance_bearings[k].radial_clearance
    rolling = 2 * np.pi * 20.0 * rig.contact.rotor_radius / r_r
    np.testing.assert_allclose(blk.truth["race_speed"][-32:, k], rolling, rtol=0.01)
    for j, c in enumerate(rig.clearance_bearings):  # retainers have no race
        if c.kind == "retainer":
            assert np.all(blk.truth["race_speed"][:, j] == 0.0)
    held = dataclasses.replace(rig, contact=dataclasses.replace(rig.contact, race_inertia=0.0))
    sim = PlantSimulator(held, sc, sc.samples_per_rev)
    assert np.all(sim.advance(int(0.2 * sim.fs)).truth["race_speed"] == 0.0)


def _diverging_controller_run(rig, race_inertia, revolutions=10, spr=32):
    """
    The worst case: bang-bang velocity feedback of the full 1 kN per axis on the inner
    probes (negative damping) at the third critical speed; returns (excess, f_max) per
    clearance bearing (m, N). The retainers are left out: their bronze bush has no race.
    """
    rig = dataclasses.replace(
        rig,
        clearance_bearings=tuple(c for c in rig.clearance_bearings if c.kind == "auxiliary"),
        contact=dataclasses.replace(rig.contact, race_inertia=race_inertia),
    )
    sc = load_scenario(SCENARIOS / "sync_force_150N_third_critical.yaml", rig)
    sim = PlantSimulator(rig, sc, spr)
    clearance = np.array([c.radial_clearance for c in rig.clearance_bearings])
    inner = list(rig.feedback_channels)
    prev, force = np.zeros(8), np.zeros((1, 4))
    radius, f_max = np.zeros(len(clearance)), np.zeros(len(clearance))
    for _ in range(revolutions * spr):
        blk = sim.advance(1, force)
        y = blk.displacement[0]
        force = 1000.0 * np.sign(y[inner] - prev[inner])[None, :]
        prev = y
        j = blk.truth["journal_displacement"][0]
        radius = np.maximum(radius, np.hypot(j[:, 0], j[:, 1]))
        f_max = np.maximum(f_max, blk.truth["contact_force"][0])
    return radius - clearance, f_max


@pytest.mark.slow
def test_rolling_races_bound_a_diverging_controller_at_full_force(rig):
    excess, f_max = _diverging_controller_run(rig, rig.contact.race_inertia)
    assert np.all(f_max > 1e3)  # the controller does drive the rotor onto both bearings
    # the penetration is the Hertzian deflection of the largest force, no more ...
    hertz = (f_max / rig.contact.hertz_stiffness) ** (2 / 3)
    assert np.all(excess <= 1.05 * hertz)
    # ... and that force stays an impact's, well inside the clearance (measured 13 kN, 175 µm)
    assert np.all(excess < 0.5 * 750e-6)
    # with the races held at rest, friction feeds whirl: forces of ~10^5 N, mm penetration
    held_excess, held_f = _diverging_controller_run(rig, 0.0)
    assert np.all(held_f > 5 * f_max) and np.all(held_excess > 2 * excess)
