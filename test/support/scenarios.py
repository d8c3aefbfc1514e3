"""Scenario mappings shared by tests (the rig itself stays in config/rig.yaml)."""

from __future__ import annotations

#: Samples per revolution of the shared scenarios.
SAMPLES_PER_REV = 32


def first_critical_mass_loss(
    duration: float, mass_loss_time: float = 1.5, name: str = "restart"
) -> dict:
    """
    430 g cm lost at D1 at the first critical speed (thesis section 8.5.3), 32 samples/rev.

    Over a 50 g cm residual unbalance at D1, with 0.2 um probe noise: the scenario of the
    restart, starvation, lost-command, drain, determinism and recorder-bag tests.

    Parameters
    ----------
    duration : float
        Simulated s.
    mass_loss_time : float
        Simulated s of the loss.
    name : str
        Scenario name.

    Returns
    -------
    dict
        For :func:`amb_plant_sim.scenario.scenario_from_dict` or a YAML file.
    """
    return {
        "name": name,
        "speed": {"role": "first_critical"},
        "duration": duration,
        "samples_per_rev": SAMPLES_PER_REV,
        "measurement_noise": 2.0e-7,
        "events": [
            {"kind": "unbalance", "time": 0.0, "disk": "D1", "me": 0.5e-3, "angle": 0.0},
            {"kind": "mass_loss", "time": mass_loss_time, "disk": "D1", "me": 4.3e-3, "angle": 0.0},
        ],
    }


def steady_unbalance(
    name: str,
    duration: float,
    samples_per_rev: int = 16,
    hz: float = 20.0,
    measurement_noise: float | None = None,
) -> dict:
    """
    A 10 g cm unbalance at D1 from the start, at a constant speed away from the criticals.

    The scenario of the tests about the run's machinery (recorder counts, a stalled or killed
    run), where the dynamics only need to be steady and cheap.

    Parameters
    ----------
    name : str
        Scenario name.
    duration : float
        Simulated s.
    samples_per_rev : int
        Samples per revolution.
    hz : float
        Rotor speed, Hz.
    measurement_noise : float, optional
        Probe noise, m RMS (default: the scenario default).

    Returns
    -------
    dict
        For :func:`amb_plant_sim.scenario.scenario_from_dict` or a YAML file.
    """
    scenario = {
        "name": name,
        "speed": {"hz": hz},
        "duration": duration,
        "samples_per_rev": samples_per_rev,
        "events": [{"kind": "unbalance", "time": 0.0, "disk": "D1", "me": 1.0e-3, "angle": 0.0}],
    }
    if measurement_noise is not None:
        scenario["measurement_noise"] = measurement_noise
    return scenario
