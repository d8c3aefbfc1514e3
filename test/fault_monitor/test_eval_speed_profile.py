"""amb-fault-eval on a speed profile (issue 19): the run reaches its duration and the scoring
uses the simulator's sample instants, not ``sample / fs`` at the starting speed.

References are closed forms of a linear ramp ``f(t) = f0 + a t``: revolutions
``R(t) = f0 t + a t^2 / 2``, sample ``n`` at ``R = n / spr``. The simulator holds the speed
(rounded to ``simulation.speed_quantum``) over each sample, so its instants follow the closed
form to within the speed change over one sample, accumulated: a sample in a few hundred here.
"""

import math

import numpy as np
import pytest
import yaml

from amb_apps.evaluation import run_case, simulate_case
from amb_common.rig import load_rig
from amb_plant_sim.scenario import scenario_from_dict
from amb_plant_sim.simulator import PlantSimulator

pytestmark = pytest.mark.slow  # simulates a run-up sample by sample

SPR = 32
F0, F1, DURATION = 30.0, 31.0, 4.0  # Hz, Hz, s: a slow run-up (few discretisations to build)
LOSS = 3.0  # s: sample ceil(LOSS * SPR * F0) comes 37 ms (35 samples) earlier on the ramp


@pytest.fixture(scope="module")
def rig():
    return load_rig()


def _ramp(extra: dict | None = None) -> dict:
    return {
        "name": "run_up",
        "speed_profile": [{"time": 0.0, "hz": F0}, {"time": DURATION, "hz": F1}],
        "duration": DURATION,
        "samples_per_rev": SPR,
        **(extra or {}),
    }


def _revolutions(t: float) -> float:
    return F0 * t + 0.5 * (F1 - F0) / DURATION * t * t


def test_samples_before_the_end_of_a_run_up_follow_the_ramp(rig) -> None:
    sim = PlantSimulator(rig, scenario_from_dict(_ramp(), rig), SPR, 0)
    n = sim.samples_before(DURATION)
    closed = math.ceil(SPR * _revolutions(DURATION))  # samples with R(t_n) < R(DURATION)
    assert abs(n - closed) <= 2, (n, closed)
    assert n > round(DURATION * SPR * F0)  # more than the starting speed gives
    block = sim.advance(n)
    assert block.time[-1] < DURATION <= sim.time  # the last sample before the end, no more
    assert sim.samples_before(DURATION) == 0


def test_a_mass_loss_on_a_run_up_is_scored_on_the_real_instants(rig, tmp_path) -> None:
    path = tmp_path / "run_up.yaml"
    path.write_text(
        yaml.safe_dump(
            _ramp(
                {
                    "measurement_noise": 0.2e-6,
                    "events": [
                        {"kind": "unbalance", "time": 0.0, "disk": "D1", "me": 0.5e-3},
                        {"kind": "mass_loss", "time": LOSS, "disk": "D1", "me": 4.3e-3},
                    ],
                    "expect": [{"fault": "MASS_LOSS", "time": LOSS}],
                }
            )
        )
    )
    case = simulate_case(path, rig)
    times = case.block.time
    assert times[-1] < DURATION <= times[-1] + 1.0 / (SPR * F0)  # the whole run
    (match,) = run_case(case, "haar").matches
    f_loss = F0 + (F1 - F0) * LOSS / DURATION  # Hz at the loss
    assert match["predicted"] == "MASS_LOSS"
    assert LOSS <= match["true_onset_time"] < LOSS + 1.0 / (SPR * f_loss)
    assert match["speed_hz_at_onset"] == pytest.approx(f_loss, abs=0.01)  # speed_quantum
    true = match["true_onset_sample"]
    assert true == int(np.searchsorted(times, LOSS))
    # delays in ms from the instants: samples over the sample rate at that speed
    delay = match["detection_delay_samples"]
    assert match["detection_delay_ms"] == pytest.approx(1e3 * delay / (SPR * f_loss), rel=0.01)
    assert match["detection_delay_revs"] == delay / SPR
