"""
control_limit on the rig: the linear program's response is what the simulator does with the
optimal force (superposition on the real, nonlinear simulation path), within every limit, and
no better than what has happened before any force can act.
"""

from pathlib import Path

import numpy as np
import pytest

from amb_plant_sim.control_limit import control_limit, replay_force
from amb_plant_sim.errors import BoundExceededError
from amb_plant_sim.scenario import load_scenario

SCENARIOS = Path(__file__).resolve().parents[2] / "config" / "scenarios"
SPR = 32  # a coarser sampling than the scenario's keeps the linear program small


@pytest.fixture(scope="module")
def mass_loss(rig):
    sc = load_scenario(SCENARIOS / "mass_loss_first_critical.yaml", rig)
    fault = next(e.time for e in sc.events if e.kind == "mass_loss")
    return sc, fault


@pytest.fixture(scope="module")
def limit_i2(rig, mass_loss):
    sc, fault = mass_loss
    return control_limit(rig, sc, SPR, fault, 2, revolutions=1, tail_revolutions=2, settle=False)


def test_replay_on_the_simulator_gives_the_programs_response(rig, mass_loss, limit_i2):
    r = limit_i2
    # the simulator, with the optimal force, reproduces the predicted displacement: the
    # tolerance is 1e-6 of the peak (solver tolerances on um-scaled rows), far below the
    # 0.2 um probe noise the scenario would add
    np.testing.assert_allclose(
        r.replay_displacement[: r.end], r.displacement[: r.end], rtol=0, atol=1e-6 * r.peak
    )
    assert r.replay_peak == pytest.approx(r.peak, rel=1e-5)
    assert r.replay_contacts == 0 and r.replay_step_by_step == 0


def test_the_limit_is_bounded_by_what_happened_before_the_force_and_by_pid(limit_i2):
    r = limit_i2
    assert r.peak >= r.floor * (1 - 1e-9)
    # the floor is the PID-only response up to k0, which the force cannot change
    n_a = (r.fault_sample // r.samples_per_rev) * r.samples_per_rev
    assert r.floor == pytest.approx(np.abs(r.pid_displacement[n_a : r.k0 + 1]).max(), rel=1e-12)
    assert r.peak < r.pid_peak
    assert r.k0 == n_a + 2 * r.samples_per_rev


def test_the_force_and_the_total_control_force_stay_within_the_limit(rig, mass_loss, limit_i2):
    sc, _ = mass_loss
    r = limit_i2
    limit = rig.amb.force_limit
    assert np.abs(r.force).max() <= limit * (1 + 1e-6)
    block = replay_force(rig, sc, SPR, r.force, r.k0)
    assert np.abs(block.bearing_force).max() <= limit * (1 + 1e-6)
    # the replay's inner channels are the ones the limit is about
    np.testing.assert_array_equal(
        block.displacement[:, rig.feedback_channels], r.replay_displacement
    )


def test_a_small_force_limit_costs_peak(rig, mass_loss, limit_i2):
    sc, fault = mass_loss
    weak = control_limit(
        rig, sc, SPR, fault, 2, revolutions=1, tail_revolutions=2, added_limit=5.0, settle=False
    )
    assert np.abs(weak.force).max() <= 5.0 * (1 + 1e-6)
    assert weak.peak > limit_i2.peak * 1.05
    assert weak.replay_peak == pytest.approx(weak.peak, rel=1e-5)


def test_contact_before_any_force_can_act_is_reported(rig):
    sc = load_scenario(SCENARIOS / "mass_loss_contact_case2.yaml", rig)
    fault = next(e.time for e in sc.events if e.kind == "mass_loss")
    with pytest.raises(BoundExceededError, match="clearance"):
        control_limit(rig, sc, SPR, fault, 2, revolutions=1, tail_revolutions=2, settle=False)


def test_no_force_within_the_limits_that_keeps_the_rotor_clear_is_reported(rig):
    """The 150 N synchronous step at the first critical speed: with PID alone the rotor ends on
    an auxiliary bearing (simulator truth, the premise); with a 10 N added force no controller
    can keep it clear, and that is the physical verdict (``BoundExceededError``, which
    ``amb-compare`` and ``amb-bound`` report as "no limit"), not a failure of the program."""
    from amb_plant_sim.simulator import PlantSimulator

    sc = load_scenario(SCENARIOS / "sync_force_150N_first_critical.yaml", rig)
    step = next(e.time for e in sc.events if e.kind == "sync_force")
    n = round(sc.duration * sc.speed_hz * SPR)
    assert PlantSimulator(rig, sc, SPR, 0).advance(n).truth["contact"].any()  # the premise
    with pytest.raises(BoundExceededError, match="infeasible"):
        control_limit(
            rig, sc, SPR, step, 2, revolutions=1, tail_revolutions=2, added_limit=10.0,
            settle=False,
        )  # fmt: skip
