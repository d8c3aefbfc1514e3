"""The ``stop`` hook of ``run_closed_loop``: ends the run after the period it returns True."""

import numpy as np

from amb_apps.closed_loop import run_closed_loop
from amb_common.paths import config_file
from amb_common.rig import load_rig
from amb_controller.config import ControllerConfig
from amb_plant_sim.scenario import load_scenario

SPR = 64


def test_stop_ends_the_run_after_the_period_and_leaves_earlier_periods_unchanged():
    rig = load_rig()
    scenario = load_scenario(config_file("scenarios/sync_force_200N_22Hz.yaml"), rig)
    cfg = ControllerConfig(samples_per_rev=SPR, controller="none")
    seen = []

    def stop(loop):
        seen.append(loop.k)
        return loop.k == 7

    short = run_closed_loop(rig, scenario, cfg, stop=stop)
    full = run_closed_loop(rig, scenario, cfg)
    assert seen == [1, 2, 3, 4, 5, 6, 7]  # called once after each period, with k periods run
    assert short.displacement.shape == (7 * SPR, 8)
    assert short.phasor.shape == (7, 8)
    assert full.phasor.shape[0] == round(scenario.duration * scenario.speed_hz)
    np.testing.assert_array_equal(short.displacement, full.displacement[: 7 * SPR])
    np.testing.assert_array_equal(short.time, full.time[: 7 * SPR])
