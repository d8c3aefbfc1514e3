"""A step of the applied control force is a control transient, not a fault (monitor step 5).

The soak run's false contact rebuilt on the plant core (no ROS): 67 Hz, the soak's unbalance
(1 kg mm on D1), 0.2 um probe noise, and a synchronous wavelet force at both bearings that
nulls the 1 x response of the inner sensors (planes 2 and 3), as the transient controller held
them at 2 um with 65 N in the soak. The force is found by least squares from the plant's own
1 x responses (the unbalance alone, a unit force at each bearing), not from the monitor. One
late command answers a period with zero force: the inner sensors jump from about 0.5 to 27 um
and back with no contact (simulator truth). Told nothing, the monitor calls it a contact with
each wavelet (the soak's AUX_BEARING_CONTACT); told the applied force, it reports nothing and
counts one control transient. A real contact (the suite's AB1 contact at 29 Hz) is still found
when the monitor is fed the (zero) wavelet force the simulation applied.
"""

from pathlib import Path

import numpy as np
import pytest

from amb_fault_monitor.evaluation import simulate_case
from amb_fault_monitor.events import FaultType
from amb_fault_monitor.monitor import FaultMonitor, MonitorConfig
from amb_fault_monitor.records import FilterbankAdapter
from amb_plant_sim.rig import load_rig
from amb_plant_sim.scenario import scenario_from_dict
from amb_plant_sim.simulator import PlantSimulator

SUITE = Path(__file__).resolve().parents[2] / "config" / "scenarios" / "faults"
SPR = 32
HZ = 67.0  # bench/reliability.py's soak speed
DURATION = 4.0  # s
DROP = round(2.5 * HZ) * SPR  # first sample of the period answered with zero force
WAVELETS = ("haar", "db2", "db4")


def _scenario(rig, noise: float, me: float = 1.0e-3, duration: float = DURATION):
    return scenario_from_dict(
        {
            "name": "soak_late_command",
            "speed": {"hz": HZ},
            "duration": duration,
            "samples_per_rev": SPR,
            "measurement_noise": noise,
            "events": [{"kind": "unbalance", "time": 0.0, "disk": "D1", "me": me}],
        },
        rig,
    )


def _synchronous(c: np.ndarray, n: int) -> np.ndarray:
    """(n, 4) N: forward synchronous force of complex amplitude ``c[b]`` at bearing ``b``."""
    z = np.exp(2j * np.pi * np.arange(n) / SPR)[:, None] * np.asarray(c)[None, :]
    force = np.zeros((n, 4))
    force[:, 0::2], force[:, 1::2] = z.real, z.imag
    return force


def _phasors(rig, c: np.ndarray, me: float) -> np.ndarray:
    """Complex 1 x amplitude of the 8 sensors over the last revolution of 1.5 s (no noise)."""
    n = round(1.5 * HZ * SPR)
    sim = PlantSimulator(rig, _scenario(rig, 0.0, me, 1.5), SPR, 0)
    d = sim.advance(n, wavelet_force=_synchronous(c, n)).displacement[-SPR:]
    return 2 * (d * np.exp(-2j * np.pi * np.arange(n - SPR, n) / SPR)[:, None]).mean(axis=0)


@pytest.fixture(scope="module")
def late_command():
    """The soak-like run with one period of zero force: (block, applied force)."""
    rig = load_rig()
    unbalance = _phasors(rig, np.zeros(2), 1.0e-3)
    unit = np.array([_phasors(rig, np.eye(2)[b], 0.0) for b in (0, 1)]).T  # (8, 2)
    inner = slice(2, 6)  # x2, y2, x3, y3
    c, *_ = np.linalg.lstsq(unit[inner], -unbalance[inner], rcond=None)
    n = round(DURATION * HZ * SPR)
    force = _synchronous(c, n)
    force[DROP : DROP + SPR] = 0.0
    block = PlantSimulator(rig, _scenario(rig, 2.0e-7), SPR, 0).advance(n, wavelet_force=force)
    return block, force


def _run(
    block, wavelet: str, force: np.ndarray | None, spr: int = SPR
) -> tuple[FaultMonitor, list]:
    adapter = FilterbankAdapter(spr, wavelet)
    monitor = FaultMonitor(MonitorConfig(spr))
    events = []
    for i in range(block.sample_index.size):
        n = int(block.sample_index[i])
        if force is not None:
            monitor.control_force(n, force[i])
        rec = adapter.step(n, block.displacement[i], block.angle[i], block.omega[i])
        events += monitor.step(rec)
    return monitor, events


def test_the_late_command_moves_the_rotor_as_in_the_soak_without_contact(late_command):
    block, force = late_command
    inner = np.hypot(block.displacement[:, 2], block.displacement[:, 3])
    before, after = inner[DROP - SPR : DROP].max(), inner[DROP : DROP + 4 * SPR].max()
    assert before < 2e-6 and after > 20e-6, (before, after)
    assert 60.0 <= np.abs(force[DROP - SPR : DROP]).max() <= 90.0  # N, the soak's 65 N scale
    assert not block.truth["contact"].any()


@pytest.mark.parametrize("wavelet", WAVELETS)
def test_one_late_command_is_a_control_transient_not_a_contact(late_command, wavelet):
    block, force = late_command
    _, blind = _run(block, wavelet, None)
    assert [e.fault_type for e in blind] == [FaultType.AUX_BEARING_CONTACT]  # the soak's
    monitor, events = _run(block, wavelet, force)
    assert events == []
    assert monitor.control_transients == 1
    last = monitor.last_control_transient
    assert last["classified_as"] == "AUX_BEARING_CONTACT"
    # the drop and the return: the force differs from a revolution before for two periods
    assert (last["step_first_sample_index"], last["step_last_sample_index"]) == (
        DROP,
        DROP + 2 * SPR - 1,
    )
    assert last["step_n"] == pytest.approx(np.abs(force[DROP - SPR : DROP]).max(), rel=1e-9)
    assert DROP <= last["onset_sample_index"] <= DROP + 3 * SPR


def test_a_second_late_command_in_the_ring_down_is_no_contact(late_command):
    """Five periods later a second zero period re-excites the ring-down: no contact burst."""
    block, force = late_command
    force = force.copy()
    second = DROP + 5 * SPR
    force[second : second + SPR] = 0.0
    rig = load_rig()
    block = PlantSimulator(rig, _scenario(rig, 2.0e-7), SPR, 0).advance(
        force.shape[0], wavelet_force=force
    )
    assert not block.truth["contact"].any()
    monitor, events = _run(block, "haar", force)
    assert events == []
    assert monitor.control_transients == 1


@pytest.fixture(scope="module")
def contact_case():
    return simulate_case(SUITE / "contact_ab1_29hz_sync_force.yaml", load_rig())


@pytest.mark.parametrize("wavelet", WAVELETS)
def test_a_real_contact_is_still_found_with_the_force_fed(contact_case, wavelet):
    block = contact_case.block
    spr = contact_case.samples_per_rev
    first = int(np.flatnonzero(block.truth["contact"].any(axis=1))[0]) + 1  # evaluation.py
    force = np.zeros((block.sample_index.size, 4))  # the wavelet force the simulation applied
    monitor, events = _run(block, wavelet, force, spr)
    contacts = [e for e in events if e.fault_type == FaultType.AUX_BEARING_CONTACT]
    assert contacts, [e.fault_type.name for e in events]
    assert first - spr <= contacts[0].onset_sample_index <= first + 20 * spr  # the suite's match
    assert monitor.control_transients == 0
