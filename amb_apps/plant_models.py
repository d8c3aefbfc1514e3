"""
Controller models built from the simulated rig (application layer).

These run the plant model, so they sit above the controller core: the baselines' models
(:mod:`amb_controller.baselines`), the sampled-harmonic one from the FE model's PID closed
loop and the influence coefficients from trial injections on the simulated rig, and the
multilevel controller's per-level models (:mod:`amb_controller.multilevel`) from the chapter-6
FE route or a simulated identification (section 6.4), and the sample-domain model of the
early action on a sudden unbalance (:mod:`amb_controller.early_action`).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from amb_apps.closed_loop import fe_model, identify_model
from amb_common.names import N_AXES, N_SENSORS
from amb_controller.baselines import BaselineSettings, fourier_model
from amb_controller.early_action import EarlyActionConfig
from amb_controller.early_model import EarlyActionModel, EarlyModelBank
from amb_controller.errors import ControllerValueError
from amb_controller.fourier_basis import (
    complex_from_real,
    fourier_control_basis,
    fourier_measurement_basis,
    real_gain,
)
from amb_controller.model_file import WaveletModel
from amb_controller.wavelet_dynamics import wavelet_markov
from amb_plant_sim.closed_loop import build_closed_loop
from amb_plant_sim.control_limit import linear_rig
from amb_plant_sim.events import Event
from amb_plant_sim.simulator import PlantSimulator

__all__ = [
    "band_speeds",
    "early_action_bank",
    "early_action_model",
    "early_action_planes",
    "harmonic_model",
    "influence_by_trials",
    "level_models",
]


def harmonic_model(rig, omega: float, config, n_terms: int = 60) -> WaveletModel:
    """
    Sampled-harmonic model ``G_h`` of the FE PID closed loop (Markov parameters, eq. B.2).

    Parameters
    ----------
    rig : amb_common.rig.Rig
        Rig description.
    omega : float
        Running speed in rad/s.
    config : ControllerConfig
        ``samples_per_rev``, ``sensors``, ``inverse_order``, ``inverse_regularisation``,
        ``delay_periods`` are used.
    n_terms : int
        Markov parameters kept (periods).

    Returns
    -------
    WaveletModel
        ``wavelet = "fourier"``, ``source = "fe-harmonic"``; Fourier labels.

    """
    cl = build_closed_loop(rig, omega)
    n = config.period_samples
    cb = fourier_control_basis(n)
    mb = fourier_measurement_basis(n, config.sensors)
    markov = wavelet_markov(
        cl.A, cl.B_u, cl.output(cl.plant.C_s), 2 * math.pi / omega, cb, mb, n_terms
    )
    return fourier_model(markov, config, omega, "fe-harmonic", cb, mb)


def influence_by_trials(
    rig, scenario, config, settings: BaselineSettings | None = None, seed: int = 0
) -> WaveletModel:
    """
    Identify the steady 1 x influence coefficients ``T`` by trial injections (eq. B.1).

    The simulated rig runs PID only at the scenario speed with the scenario's residual
    unbalance (every other event dropped). After ``trial_settle`` periods the 1 x response
    is averaged over ``trial_average`` periods (reference); then each axis in turn carries a
    cosine force of ``trial_force`` N (the others none) and the averaged response change,
    divided by the trial's complex coefficient, is the column of ``T`` (the sine injection
    is redundant for a linear time-invariant plant). Noise averages down as
    ``1/sqrt(trial_average N)``.

    Parameters
    ----------
    rig : amb_common.rig.Rig
    scenario : amb_plant_sim.scenario.Scenario
        Resolved scenario.
    config : ControllerConfig
        ``samples_per_rev``, ``sensors``, ``delay_periods``.
    settings : BaselineSettings, optional
    seed : int
        Measurement-noise seed.

    Returns
    -------
    WaveletModel
        One Markov term: ``markov[0]`` is the real block form of ``T``
        (``source = "trial-injection"``); ``inverse`` its least-squares inverse.

    """
    s = settings or BaselineSettings()
    quiet = replace(
        scenario, events=tuple(e for e in scenario.events if e.kind == "unbalance"), duration=1e6
    )
    n = config.period_samples
    plant = PlantSimulator(rig, quiet, config.samples_per_rev, seed)
    cb = fourier_control_basis(n)
    mb = fourier_measurement_basis(n, config.sensors)
    weights = mb.weights  # (n_y, 8, N)

    def response(force: np.ndarray) -> np.ndarray:
        for _ in range(s.trial_settle):
            plant.advance(n, force)
        acc = np.zeros(mb.n_coefficients)
        for _ in range(s.trial_average):
            block = plant.advance(n, force)
            acc += np.einsum("icn,nc->i", weights, block.displacement)
        return complex_from_real(acc / s.trial_average)

    reference = response(np.zeros((n, N_AXES)))
    u = s.trial_force * math.sqrt(n / 2.0)  # cos coefficient of a trial_force N sinusoid
    columns = []
    for axis in range(N_AXES):
        coeffs = np.zeros(cb.n_coefficients)
        coeffs[axis] = u
        force = np.einsum("i,icn->nc", coeffs, cb.weights)
        columns.append((response(force) - reference) / u)  # U = u (real cos) -> complex u
    t = np.stack(columns, axis=1)
    markov = real_gain(t)[None]
    return fourier_model(markov, replace(config, inverse_order=0), 2 * math.pi * scenario.speed_hz,
                  "trial-injection", cb, mb)  # fmt: skip


def level_models(rig, omega: float, config, route: str = "fe", scenario=None,
                 seed: int = 0) -> dict[int, WaveletModel]:  # fmt: skip
    """
    Return each configured level's own model, obtained with that level alone.

    Parameters
    ----------
    rig : amb_common.rig.Rig
    omega : float
        Running speed in rad/s.
    config : ControllerConfig
        Levels, wavelet, samples per period, sensors, inverse order.
    route : str
        ``fe`` (chapter-6 route, :func:`amb_apps.closed_loop.fe_model` with
        ``levels = (p,)``) or ``identify`` (section 6.4 step identification on the
        simulated rig with only level p stepped, :func:`~amb_apps.closed_loop.
        identify_model`; needs ``scenario``).
    scenario : amb_plant_sim.scenario.Scenario, optional
        For ``identify``: speed, unbalance and noise of the identification run.
    seed : int
        Noise seed of the identification.

    Returns
    -------
    dict of int to WaveletModel

    """
    if route not in ("fe", "identify"):
        raise ControllerValueError(f"route must be 'fe' or 'identify', got {route!r}")
    if route == "identify" and scenario is None:
        raise ControllerValueError("route 'identify' needs the scenario to identify on")
    out = {}
    for p in config.levels:
        cfg = replace(config, levels=(int(p),))
        if route == "fe":
            out[int(p)] = fe_model(rig, omega, cfg)
        else:
            sc = replace(scenario, speed_hz=omega / (2 * math.pi))
            out[int(p)] = identify_model(rig, sc, cfg, seed=seed)
    return out


def early_action_planes(rig) -> tuple[str, ...]:
    """The planes of :func:`early_action_model`, in its order: every disk, then both AMBs."""
    return (*(d.tag for d in rig.disks), *(b.tag for b in rig.bearings[:2]))


def early_action_model(rig, scenario, samples_per_rev: int, horizon_periods: int = 6):
    """
    The sample-domain model of :mod:`amb_controller.early_action` from the FE route.

    Runs the simulated rig's PID loop, linearised (:func:`amb_plant_sim.control_limit
    .linear_rig`), noise-free, at ``scenario``'s constant speed: 1 N held over one sample on
    each bearing axis (the bearing Markov parameters), and a unit sudden unbalance (1 kg m,
    angle 0 and pi/2) appearing at a sample instant in each disk's plane and at each AMB's
    node (planes named by the bearings' tags: a synchronous force ``F`` through the AMB,
    section 8.5.2, is the unbalance ``F / Omega^2`` there). Sensors: all eight, so that the
    estimate uses every probe and the clearance check sees the rotor's ends (with the inner
    four only, a plan that held the inner probes swung the ends into the retainers on the
    figure-5.27 case 1); the plan minimises the feedback sensors, the controllers' objective.

    Parameters
    ----------
    rig : amb_common.rig.Rig
    scenario : amb_plant_sim.scenario.Scenario
        Resolved, constant speed (only its speed is used).
    samples_per_rev : int
    horizon_periods : int
        ``L / N`` of the bearing responses (the plane responses run 4 periods longer).

    Returns
    -------
    amb_controller.early_action.EarlyActionModel
    """
    N = int(samples_per_rev)
    L = horizon_periods * N
    lp = L + 4 * N
    fs = scenario.speed_hz * N
    lin = linear_rig(rig)
    quiet = replace(scenario, events=(), measurement_noise=0.0, duration=(2 * N + lp + 2) / fs)
    still = PlantSimulator(lin, quiet, N)
    bearing = np.stack([b.displacement for b in still.pulse_responses(L)], axis=2)
    s0 = 2 * N  # the loss appears at this sample
    omega = 2 * math.pi * scenario.speed_hz
    sources = [("mass_loss", {"disk": d.tag, "me": 1.0}) for d in rig.disks]
    # a synchronous force through an AMB (the thesis's test disturbance, section 8.5.2) is the
    # unbalance me = F / omega^2 at the bearing's node (eq. 3.3): per 1 kg m, F = omega^2
    sources += [("sync_force", {"bearing": b, "amplitude": omega**2}) for b in (1, 2)]
    names = early_action_planes(rig)  # the same order
    planes = []
    for kind, params in sources:
        pair = []
        for angle in (0.0, math.pi / 2):
            # the same simulator for every source: its discretisation is built once
            still.reset()
            still.inject(Event(kind, s0 / fs, None, {**params, "angle": angle}))
            pair.append(still.advance(s0 + lp).displacement[s0:])
        planes.append(np.stack(pair, axis=2))
    return EarlyActionModel(
        samples_per_rev=N,
        bearing_markov=bearing,
        plane_responses=np.array(planes),
        planes=names,
        sensors=tuple(range(N_SENSORS)),  # displacement's columns [x1, y1, .., x4, y4]
        objective=tuple(rig.feedback_channels),
        clearance=rig.probe_nearest_clearance,  # the sensors are the eight channels
        omega=omega,
        slew_rate=rig.amb.force_slew_rate,
        source="fe",
    )


def early_action_bank(rig, scenario, samples_per_rev: int, speeds_hz, progress=None):
    """
    :func:`early_action_model` at each of ``speeds_hz`` (Hz), as an :class:`EarlyModelBank`.

    ``progress(k, K, hz)``, if given, is called before each model (a bank of tens of models
    takes seconds).
    """
    speeds = sorted({float(hz) for hz in speeds_hz})
    if not speeds or speeds[0] <= 0.0:
        raise ValueError(f"speeds must be > 0 Hz, got {speeds}")
    models = []
    for k, hz in enumerate(speeds):
        if progress is not None:
            progress(k, len(speeds), hz)
        models.append(early_action_model(rig, replace(scenario, speed_hz=hz), samples_per_rev))
    return EarlyModelBank(tuple(models))


def band_speeds(speed_hz: float, percent: float) -> list[float]:
    """Speeds (Hz) covering ``percent`` % below to above ``speed_hz``, ratio ``1 + 2 tol`` apart.

    ``tol`` is the early action's ``speed_tolerance``, relative to the measured speed: a speed
    ``w`` between neighbours ``w_j`` and ``w_j (1 + 2 tol)`` is at most ``tol w_j <= tol w``
    from the nearer, so every speed of the band has a model within the tolerance (an evenly
    spaced grid would leave the midpoints below the middle speed out).
    """
    if not 0.0 < percent <= 50.0:
        raise ValueError(f"band {percent} %: expected a percentage in (0, 50]")
    ratio = 1.0 + 2.0 * EarlyActionConfig().speed_tolerance
    p = percent / 100.0
    up = math.ceil(math.log1p(p) / math.log(ratio) - 1e-9)
    down = math.ceil(-math.log1p(-p) / math.log(ratio) - 1e-9)
    return [float(speed_hz * ratio**j) for j in range(-down, up + 1)]
