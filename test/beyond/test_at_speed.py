"""amb-compare's speed cases: at another speed the fault keeps its revolution and phase."""

import math

import pytest

from amb_apps.closed_loop import first_fault
from amb_apps.compare_cases import at_speed
from amb_common.paths import config_file
from amb_common.rig import load_rig
from amb_plant_sim.control_limit import fault_sample
from amb_plant_sim.scenario import load_scenario

SPR = 64


@pytest.mark.parametrize("factor", [0.9, 1.1])
def test_the_fault_keeps_its_sample_and_the_run_its_revolutions(factor):
    nominal = load_scenario(config_file("scenarios/mass_loss_first_critical.yaml"), load_rig())
    fast = at_speed(nominal, nominal.speed_hz * factor)
    assert fast.speed_hz == pytest.approx(nominal.speed_hz * factor, rel=1e-12)
    k0 = fault_sample(nominal, first_fault(nominal).time, SPR)
    k1 = fault_sample(fast, first_fault(fast).time, SPR)
    assert k1 == k0  # the same revolution, the same phase in it
    # and the same fraction of that sample: the same rotor angle
    angle = [first_fault(s).time * s.speed_hz for s in (nominal, fast)]
    assert angle[1] == pytest.approx(angle[0], rel=1e-12)
    revs = [s.duration * s.speed_hz for s in (nominal, fast)]
    assert revs[1] == pytest.approx(revs[0], rel=1e-12)
    # the other events (the residual unbalance at 0 s) are where they were
    others = [(e.kind, e.time) for e in nominal.events if e is not first_fault(nominal)]
    assert [(e.kind, e.time) for e in fast.events if e is not first_fault(fast)] == others
    assert not math.isclose(first_fault(fast).time, first_fault(nominal).time)


def test_at_its_own_speed_the_scenario_is_unchanged():
    nominal = load_scenario(config_file("scenarios/mass_loss_first_critical.yaml"), load_rig())
    assert at_speed(nominal, nominal.speed_hz) == nominal
