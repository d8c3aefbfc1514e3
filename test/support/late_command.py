"""The soak run's late command rebuilt on the plant core (no ROS, not the monitor).

67 Hz (``bench/reliability.py``'s soak speed), the soak's unbalance (1 kg mm on D1), 0.2 um
probe noise, and a synchronous wavelet force at both bearings that nulls the 1 x response of
the inner sensors (planes 2 and 3), as the transient controller held them at 2 um with 65 N in
the soak. The force is found by least squares from the plant's own 1 x responses (the
unbalance alone, a unit force at each bearing). Late commands answer whole periods with zero
force.
"""

from __future__ import annotations

import numpy as np

from amb_common.rig import load_rig
from amb_plant_sim.scenario import scenario_from_dict
from amb_plant_sim.simulator import MeasurementBlock, PlantSimulator

SPR = 32
HZ = 67.0
UNBALANCE = 1.0e-3  # kg m on D1
NOISE = 2.0e-7  # m


def _scenario(rig, duration: float, noise: float, me: float):
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


def synchronous(c: np.ndarray, n: int) -> np.ndarray:
    """(n, 4) N: forward synchronous force of complex amplitude ``c[b]`` at bearing ``b``."""
    z = np.exp(2j * np.pi * np.arange(n) / SPR)[:, None] * np.asarray(c)[None, :]
    force = np.zeros((n, 4))
    force[:, 0::2], force[:, 1::2] = z.real, z.imag
    return force


def _phasors(rig, c: np.ndarray, me: float) -> np.ndarray:
    """Complex 1 x amplitude (m) of the 8 sensors over the last revolution of 1.5 s, no noise."""
    n = round(1.5 * HZ * SPR)
    sim = PlantSimulator(rig, _scenario(rig, 1.5, 0.0, me), SPR, 0)
    d = sim.advance(n, wavelet_force=synchronous(c, n)).displacement[-SPR:]
    return 2 * (d * np.exp(-2j * np.pi * np.arange(n - SPR, n) / SPR)[:, None]).mean(axis=0)


def nulling_force() -> np.ndarray:
    """Complex amplitude (N) per bearing of the force that nulls the inner sensors' 1 x."""
    rig = load_rig()
    unbalance = _phasors(rig, np.zeros(2), UNBALANCE)
    unit = np.array([_phasors(rig, np.eye(2)[b], 0.0) for b in (0, 1)]).T  # (8, 2)
    inner = slice(2, 6)  # x2, y2, x3, y3
    c, *_ = np.linalg.lstsq(unit[inner], -unbalance[inner], rcond=None)
    return c


def late_command_run(
    duration: float, zero_periods: list[int], c: np.ndarray | None = None
) -> tuple[MeasurementBlock, np.ndarray]:
    """
    Simulate the run with the periods ``zero_periods`` (revolution indices) at zero force.

    Returns
    -------
    block : amb_plant_sim.simulator.MeasurementBlock
    force : numpy.ndarray
        (n, 4) N, the wavelet force applied in each sample.
    """
    rig = load_rig()
    n = round(duration * HZ * SPR)
    force = synchronous(nulling_force() if c is None else c, n)
    for k in zero_periods:
        force[k * SPR : (k + 1) * SPR] = 0.0
    sim = PlantSimulator(rig, _scenario(rig, duration, NOISE, UNBALANCE), SPR, 0)
    return sim.advance(n, wavelet_force=force), force
