"""
In-process closed loop: plant, front end, filterbank and controller pipeline in lock step.

The runner does exactly what the ROS nodes do (``ARCHITECTURE.md``, "Time", lockstep), in
one process and one thread, so that its results are those of the node graph::

    for period k:
        force_k = commands.pop(k, zeros)            # plant_sim: wait for command k (k >= i)
        block = plant.advance(N, force_k)           # N samples, force held per sample
        for each sample n of the block:
            records = bank.step(front.step(x[n], theta[n]), n)      # wavelet_filterbank
            command = pipeline.on_sample(n, records, x[n], omega)   # wavelet_controller
            (at the last sample of period k: command for k + i)

Periods ``k < i`` run with zero wavelet force (no command can exist for them). Everything
the controller sees is what a rig measures (``MeasurementBlock`` without ``truth``); the
simulator's truth is used only for the metrics that say so (contact count).

Models (``--model`` of ``amb-sim``)
-----------------------------------
* ``fe``: the chapter-6 route. Markov parameters of ``G_{p,q,a,b}`` from the FE model's
  PID closed loop (:func:`amb_plant_sim.closed_loop.build_closed_loop`) at the scenario
  speed, force per bearing axis in, the 8 sensors out, with the exact sampled projection
  of :func:`amb_controller.wavelet_dynamics.wavelet_markov`.
* ``identify``: section 6.4 on the simulated rig: the plant runs PID only at the scenario
  speed with the scenario's residual unbalance but no fault; after ``settle`` seconds each
  control coefficient is stepped in turn (:meth:`ControllerPipeline.start_identification`)
  and the Markov parameters are fitted from what the filterbank measured.
* a path: a model file written by either.

Bag
---
With a :class:`amb_apps.run_bag.BagRecorder` the run is written to a rosbag2 with the ROS
pipeline's topics and types (:mod:`amb_apps.run_bag`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from amb_common.faults import WITHDRAWN, event_status
from amb_common.names import SENSOR_NAMES
from amb_controller.baselines import HarmonicPipeline
from amb_controller.config import BASELINE_CONTROLLERS, ControllerConfig
from amb_controller.errors import ControllerValueError, NotIdentifiedError
from amb_controller.inverse import pseudo_inverse_series
from amb_controller.model_file import WaveletModel
from amb_controller.pipeline import ControllerPipeline
from amb_controller.selection import selected_control_basis, selected_measurement_basis
from amb_controller.supervisor import Command, Mode
from amb_controller.wavelet_dynamics import wavelet_markov
from amb_fault_monitor.config import MonitorConfig
from amb_fault_monitor.monitor import FaultMonitor
from amb_fault_monitor.records import CoefficientSet, SampleCoefficients
from amb_plant_sim.closed_loop import build_closed_loop
from amb_plant_sim.simulator import PlantSimulator
from amb_wavelet.analysis import AnalysisFilterbank
from amb_wavelet.frontend import FRAMES, QUADRATURES, ChannelFrontEnd

if TYPE_CHECKING:
    from amb_apps.run_bag import BagRecorder
    from amb_common.rig import Rig

__all__ = [
    "RunResult",
    "fe_model",
    "identify_model",
    "run_closed_loop",
]

#: Event kinds that are faults (the onset of the first one is "the fault" of the metrics).
FAULT_KINDS = ("mass_loss", "sync_force", "step_force", "sensor_fault", "amb_channel_loss",
               "misalignment", "base_motion")  # fmt: skip


def first_fault(scenario):
    """The scenario's earliest event of a :data:`FAULT_KINDS` kind ("the fault"), or ``None``."""
    faults = [e for e in scenario.events if e.kind in FAULT_KINDS]
    return min(faults, key=lambda e: e.time) if faults else None


@dataclass
class RunResult:
    """
    Everything one closed-loop run produced (arrays over all samples, SI units).

    Attributes
    ----------
    time : numpy.ndarray
        ``(n,)`` s.
    displacement : numpy.ndarray
        ``(n, 8)`` m, measured.
    wavelet_force : numpy.ndarray
        ``(n, 4)`` N, wavelet force applied per axis.
    bearing_force : numpy.ndarray
        ``(n, 4)`` N, total AMB control force ``K_i i`` per axis (PID + wavelet).
    contact : numpy.ndarray of bool
        ``(n, k)`` simulator truth: contact at each clearance bearing.
    phasor : numpy.ndarray of complex
        ``(K, 8)`` per period, 1 x coefficient ``x_{1,1}`` even + i odd (fixed frame, m
        sqrt(samples)).
    commands : list of Command
        One per measured period.
    fault_time : float
        Onset of the first fault event in s (0 if none).
    fault_events : list of dict
        Events of the fault monitor (empty if none ran).
    samples_per_rev : int
    omega : float
        Running speed at the end, rad/s.
    model : WaveletModel or None
    refused : str
        Why the controller was never set ACTIVE although the run asked for it: its closed loop
        on its own model is (nearly) unstable (``ControllerConfig.max_model_radius``); the run
        is then PID only. Empty otherwise.
    model_radius : float or None
        Closed-loop spectral radius of the controller on its own model
        (:func:`~amb_controller.stability.own_model_radius`; None: no controller or none to
        check).
    early_detections : list of amb_controller.early_action.Detection
        The early action's decisions (empty without ``early_model``).

    """

    time: np.ndarray
    displacement: np.ndarray
    wavelet_force: np.ndarray
    bearing_force: np.ndarray
    contact: np.ndarray
    phasor: np.ndarray
    commands: list[Command]
    fault_time: float
    samples_per_rev: int
    omega: float
    model: WaveletModel | None = None
    fault_events: list[dict] = field(default_factory=list)
    refused: str = ""
    model_radius: float | None = None
    early_detections: list = field(default_factory=list)


# ---------------------------------------------------------------------------------------------
# models
# ---------------------------------------------------------------------------------------------


def fe_model(rig, omega: float, config: ControllerConfig, n_terms: int = 60) -> WaveletModel:
    """
    Wavelet-domain model from the FE closed loop (chapter 6 route, numerical, eq. 6.19/6.34).

    Parameters
    ----------
    rig : amb_common.rig.Rig
        Rig description.
    omega : float
        Running speed in rad/s (the period is ``2 pi / omega``).
    config : ControllerConfig
        Wavelet, samples per period, levels, quadratures, inverse order.
    n_terms : int
        Markov parameters kept (periods of the impulse response).

    Returns
    -------
    WaveletModel
        ``source = "fe"``.

    """
    cl = build_closed_loop(rig, omega)
    n = config.period_samples
    cb = selected_control_basis(config)
    mb = selected_measurement_basis(config)
    markov = wavelet_markov(
        cl.A, cl.B_u, cl.output(cl.plant.C_s), 2 * math.pi / omega, cb, mb, n_terms
    )
    inverse = pseudo_inverse_series(
        markov, config.inverse_order, regularisation=config.inverse_regularisation
    )
    return WaveletModel(
        markov=markov,
        inverse=inverse,
        wavelet=config.wavelet,
        samples_per_rev=n,
        omega=float(omega),
        levels=tuple(config.levels),
        quadratures=tuple(config.quadratures),
        delay=config.delay_periods,
        source="fe",
        control_labels=cb.labels,
        measured_labels=mb.labels,
    )


def identify_model(
    rig,
    scenario,
    config: ControllerConfig,
    seed: int = 0,
    settle: float = 3.0,
    progress=None,
) -> WaveletModel:
    """
    On-line identification (section 6.4) on the simulated rig, PID only, no fault.

    Parameters
    ----------
    rig : amb_common.rig.Rig
    scenario : amb_plant_sim.scenario.Scenario
        Resolved scenario; its speed, noise and ``unbalance`` events are kept, every other
        event is dropped.
    config : ControllerConfig
        Identification order, amplitude and periods per step are taken from it.
    seed : int
        Noise seed.
    settle : float
        s of PID-only running before the first step (start-up transient).
    progress : callable, optional
        ``progress(done, total)`` per period.

    Returns
    -------
    WaveletModel
        ``source = "identification"``.

    Raises
    ------
    amb_controller.errors.ControllerValueError
        If the identification does not complete.

    """
    quiet = replace(
        scenario,
        events=tuple(e for e in scenario.events if e.kind == "unbalance"),
        duration=1e6,
    )
    cfg = replace(config, controller="none")
    loop = _Loop(rig, quiet, cfg, None, seed)
    n_settle = max(1, math.ceil(settle * scenario.speed_hz))
    for _ in range(n_settle):
        loop.period()
    ok, message = loop.pipeline.start_identification()
    if not ok:
        raise NotIdentifiedError(message)
    total = (
        n_settle
        + cfg.delay_periods
        + 2 * cfg.identification_periods_per_step * (loop.pipeline.control.n_coefficients)
        + cfg.identification_order
        + 2
    )
    for k in range(n_settle, total + 1):
        loop.period()
        if progress is not None:
            progress(k + 1, total + 1)
        if loop.pipeline.model is not None:
            return loop.pipeline.model
    raise NotIdentifiedError(
        f"identification did not complete in {total} periods: {loop.pipeline.supervisor.message}"
    )


# ---------------------------------------------------------------------------------------------
# the loop
# ---------------------------------------------------------------------------------------------


class _Loop:
    """Plant + front end + filterbank + pipeline, advanced one control period at a time."""

    def __init__(self, rig, scenario, config: ControllerConfig, model, seed, recorder=None,
                 monitor=None, baseline=None):  # fmt: skip
        self.rig = rig
        self.config = config
        self.N = config.period_samples
        spr = config.samples_per_rev
        self.plant = PlantSimulator(rig, scenario, spr, seed)
        self.front = ChannelFrontEnd(spr, FRAMES, QUADRATURES)
        self.levels = spr.bit_length()  # log2(spr) + 1, the filterbank node's default
        self.bank = AnalysisFilterbank(config.wavelet, self.levels, self.front.n_channels)
        if config.controller in BASELINE_CONTROLLERS:
            self.pipeline = HarmonicPipeline(
                config, rig.amb.force_limit, model, baseline, rig.probe_clearance
            )
        else:
            self.pipeline = ControllerPipeline(
                config,
                rig.amb.force_limit,
                model,
                channel_labels=self.front.labels,
                probe_clearance=rig.probe_clearance,
            )
        self.recorder = recorder
        self.monitor = monitor
        self.engage_on: tuple[int, ...] = ()
        self.commands: dict[int, Command] = {}
        self.k = 0
        self.blocks: list = []
        self.forces: list[np.ndarray] = []
        self.issued: list[Command] = []
        self.phasors: list[np.ndarray] = []
        self.fault_events: list[dict] = []
        r = spr.bit_length() - 1
        self._j1 = r  # filterbank level of p = 1 (1 x)
        labels = self.front.labels
        self._even = np.array([labels.index(f"fixed/even/{s}") for s in SENSOR_NAMES])
        self._odd = np.array([labels.index(f"fixed/odd/{s}") for s in SENSOR_NAMES])

    def period(self) -> None:
        k, N = self.k, self.N
        command = self.commands.pop(k, None)
        force = np.zeros((N, 4)) if command is None else command.force.T
        missing = command is None and k >= self.config.delay_periods  # STATUS_COMMAND_MISSING
        block = self.plant.advance(N, force)
        recorder = self.recorder
        meas = recorder.measurements(block, force) if recorder is not None else None
        phasor = np.zeros(8, dtype=complex)
        for s in range(N):
            n = int(block.sample_index[s])
            x = block.displacement[s]
            records = self.bank.step(self.front.step(x, block.angle[s]), n)
            for rec in records:
                if rec.level == self._j1 and rec.kind == "detail":
                    phasor = rec.values[self._even] + 1j * rec.values[self._odd]
            if meas is not None and records:
                recorder.coefficients(meas[s], n, float(block.omega[s]), records)
            if self.monitor is not None:
                found = self.monitor.step(
                    n, float(block.omega[s]), records, force[s], block.bearing_force[s],
                    block.current[s], x,
                )  # fmt: skip
                for event in found:
                    self.fault_events.append(event)
                    if recorder is not None:
                        recorder.fault_event(event, meas[s].header.stamp)
                    code = event["fault_type_code"]
                    status, revised = event_status(event.get("evidence", {}))
                    engage = code in self.engage_on and status != WITHDRAWN
                    if engage and self.pipeline.supervisor.mode == Mode.OFF:
                        self.pipeline.set_mode(Mode.ACTIVE)  # fault-triggered engagement
                    else:
                        self.pipeline.on_fault(code, status, revised)
            out = self.pipeline.on_sample(n, records, x, float(block.omega[s]), missing)
            if out is not None:
                self.commands[out.target_period] = out
                self.issued.append(out)
                if recorder is not None:
                    recorder.command(out, meas[s].header, self.pipeline)
        self.blocks.append(block)
        self.forces.append(force)
        self.phasors.append(phasor)
        self.k += 1


class _Monitor:
    """
    The ``amb_fault_monitor`` core fed as the node feeds it (optional).

    The measurement's currents and commanded forces (coil check, loop-bias check, with the
    rig's data: :meth:`FaultMonitor.from_rig`), the applied wavelet force and the filterbank
    records.
    """

    def __init__(
        self,
        samples_per_rev: int,
        wavelet: str,
        rig: Rig,
        config: MonitorConfig | None = None,
    ) -> None:
        config = config or MonitorConfig(samples_per_rev=samples_per_rev)
        self.core = FaultMonitor.from_rig(config, rig)
        self.spr = samples_per_rev
        self.wavelet = wavelet
        self.slots = []
        for frame in FRAMES:
            for quad in QUADRATURES:
                self.slots.append((frame, quad, len(self.slots) * 8))

    def step(
        self,
        n: int,
        omega: float,
        records,
        force: np.ndarray,
        bearing_force: np.ndarray,
        current: np.ndarray,
        displacement: np.ndarray,
    ) -> list[dict]:
        """
        Feed sample ``n``; return the events it decided.

        Its wavelet force and commanded bearing force (N per axis), measured control
        current (A per axis), probe readings (m) and the coefficients it completed.
        """
        # the measurement first, as the node gets it before the coefficients it completes
        # (FaultMonitor.control_force, FaultMonitor.currents, FaultMonitor.displacements)
        self.core.control_force(n, force)
        found = self.core.currents(n, bearing_force, current, omega)
        self.core.displacements(n, displacement)

        sets = tuple(
            CoefficientSet(
                r.level,
                r.kind,
                frame,
                quad,
                r.translation_index,
                r.first_sample_index,
                r.last_sample_index,
                r.values[i0 : i0 + 8],
                r.settled,
            )
            for r in records
            for frame, quad, i0 in self.slots
        )
        events = found + self.core.step(SampleCoefficients(n, omega, sets, self.wavelet))
        out = []
        for e in events:
            d = e.to_dict()
            d["fault_type_code"] = int(e.fault_type)
            out.append(d)
        return out


def run_closed_loop(
    rig,
    scenario,
    config: ControllerConfig,
    model: WaveletModel | None = None,
    seed: int = 0,
    recorder: BagRecorder | None = None,
    fault_monitor: bool = False,
    progress=None,
    baseline=None,
    engage_on: tuple[int, ...] = (),
    stop=None,
    controller=None,
    early_model=None,
    early_config=None,
    monitor_config: MonitorConfig | None = None,
) -> RunResult:
    """
    Run one scenario in lock step with the wavelet controller ACTIVE from period 0.

    A controller whose closed loop on its own model is (nearly) unstable is not set ACTIVE
    (:mod:`amb_controller.supervisor`, "A controller its own model says diverges"): the run is
    PID only and :attr:`RunResult.refused` says why.

    Parameters
    ----------
    rig : amb_common.rig.Rig
    scenario : amb_plant_sim.scenario.Scenario
        Resolved scenario (constant speed).
    config : ControllerConfig
        Controller configuration; ``controller = "none"`` runs PID only (commands of zero
        force are still exchanged every period, as between the nodes).
    model : WaveletModel, optional
        Needed unless the controller is ``none``.
    seed : int
        Measurement-noise seed.
    recorder : BagRecorder, optional
        Writes the bag.
    fault_monitor : bool
        Run the ``amb_fault_monitor`` core on the records and forward its events to the
        pipeline (``on_fault``) and the bag.
    progress : callable, optional
        ``progress(done, total)`` after each period.
    baseline : amb_controller.baselines.BaselineSettings, optional
        Settings of the ``synchronous`` / ``harmonic`` baselines (their model: a Fourier
        model from :func:`amb_controller.baselines.harmonic_model` or
        :func:`~amb_controller.baselines.influence_by_trials`).
    engage_on : tuple of int
        Fault-triggered reconfiguration (thesis section 3.3.2): when given (e.g. ``(1,)``,
        ``FaultEvent.MASS_LOSS``) the controller starts OFF (PID only) and is set ACTIVE
        when the fault monitor (``fault_monitor=True``) reports one of these fault types;
        other events take the configured ``fault_actions`` (hold on contact).
    stop : callable, optional
        ``stop(loop) -> bool``, called after each period (after ``progress``) with the loop
        state: ``loop.k`` periods run, ``loop.blocks[-1]`` the last simulator block (its
        ``truth["contact"]``), ``loop.pipeline`` (its ``supervisor.guard``), ``loop.phasors``,
        ``loop.issued``. Returning True ends the run after that period; the result then
        covers the periods run.
    controller : object, optional
        A controller to run in place of the one the pipeline builds from ``model`` (same
        interface as :class:`~amb_controller.transient.TransientController`, same measured
        and control layout as ``config``), e.g. the per-level
        :class:`~amb_controller.multilevel.MultiLevelController`; ``model`` must still be
        given (the pipeline checks its layout and reports it).
    early_model : EarlyModelBank or EarlyActionModel, optional
        Adds the early action on a sudden unbalance (:mod:`amb_controller.early_action`,
        default settings; the models of :mod:`amb_controller.early_model`) to the
        controller's commands.
    early_config : amb_controller.early_action.EarlyActionConfig, optional
        Its settings (default: the defaults).
    monitor_config : MonitorConfig, optional
        The fault monitor's settings (``fault_monitor=True``; default: the defaults at the
        run's samples per revolution).

    Returns
    -------
    RunResult

    """
    monitor = None
    if fault_monitor:
        monitor = _Monitor(config.samples_per_rev, config.wavelet, rig, monitor_config)
    loop = _Loop(rig, scenario, config, model, seed, recorder, monitor, baseline)
    loop.engage_on = tuple(int(c) for c in engage_on)
    if controller is not None:
        loop.pipeline.set_controller(controller)
    if early_model is not None:
        if config.controller in BASELINE_CONTROLLERS:
            raise ControllerValueError(
                f"the early action runs with the wavelet pipeline's controllers, not "
                f"{config.controller!r}"
            )
        loop.pipeline.set_early_model(early_model, early_config)
    if engage_on and not fault_monitor:
        raise ControllerValueError("engage_on needs fault_monitor=True (events engage control)")
    if config.controller != "none" and not engage_on:
        ok, message = loop.pipeline.set_mode(Mode.ACTIVE)
        if not ok and not loop.pipeline.supervisor.unsafe_reason():
            raise ControllerValueError(f"cannot activate the controller: {message}")
    speed = scenario.speed_hz
    n_periods = max(1, round(scenario.duration * speed))
    for k in range(n_periods):
        loop.period()
        if progress is not None:
            progress(k + 1, n_periods)
        if stop is not None and stop(loop):
            break
    blocks = loop.blocks
    fault = first_fault(scenario)
    return RunResult(
        time=np.concatenate([b.time for b in blocks]),
        displacement=np.concatenate([b.displacement for b in blocks]),
        wavelet_force=np.concatenate(loop.forces),
        bearing_force=np.concatenate([b.bearing_force for b in blocks]),
        contact=np.concatenate([b.truth["contact"] for b in blocks]),
        phasor=np.array(loop.phasors),
        commands=loop.issued,
        fault_time=float(fault.time) if fault is not None else 0.0,
        samples_per_rev=config.samples_per_rev,
        omega=float(blocks[-1].omega[-1]),
        model=loop.pipeline.model,
        fault_events=loop.fault_events,
        refused=loop.pipeline.supervisor.unsafe_reason(),
        model_radius=loop.pipeline.supervisor.radius,
        early_detections=[] if early_model is None else loop.pipeline.early.detections,
    )
