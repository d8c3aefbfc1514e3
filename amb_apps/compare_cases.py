"""The matrix of ``amb-compare``: scenarios, controller rows, and the rig and models they share.

:data:`SCENARIOS` and :data:`SPECS` name the cases (:mod:`amb_apps.compare_cli` says what
each is); :class:`Matrix` loads the rig and the scenarios once, builds each row's
``ControllerConfig`` (same force limit for every row, the rig's bearing capacity unless given)
and computes each row's model once per speed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import ClassVar

from amb_apps.closed_loop import fe_model, first_fault, run_closed_loop
from amb_apps.plant_models import (
    band_speeds,
    early_action_bank,
    harmonic_model,
    influence_by_trials,
)
from amb_common.rig import load_rig
from amb_controller.config import ControllerConfig
from amb_plant_sim.scenario import load_scenario

SCENARIOS = {
    "mass_loss_1st": "mass_loss_first_critical.yaml",
    "mass_loss_2nd": "mass_loss_second_critical.yaml",
    "sync_150N_1st": "sync_force_150N_first_critical.yaml",
    "sync_150N_2nd": "sync_force_150N_second_critical.yaml",
    "sync_150N_3rd": "sync_force_150N_third_critical.yaml",
    "contact_case2": "mass_loss_contact_case2.yaml",
}
CONTROLLERS = (
    "pid",
    "wavelet_i1",
    "wavelet_i2",
    "wavelet_sin_i1",
    "wavelet_sin_i2",
    "predictive_i1",
    "predictive_i2",
    "predictive_early_i1",
    "predictive_early_i2",
    "harmonic_i1",
    "harmonic_i2",
    "synchronous_i1",
    "synchronous_i2",
)
#: The baselines at i = 1 (issue 9's verdict: the wavelet controller at i = 1 against them).
BASELINE_ROWS = ("harmonic_i1", "synchronous_i1")
#: The baselines at each delay (issue 18: a row is compared with those at its own delay).
BASELINES_AT = {1: BASELINE_ROWS, 2: ("harmonic_i2", "synchronous_i2")}
#: The scenario of the robustness matrix (``amb-compare --robustness``).
ROBUSTNESS_SCENARIO = "mass_loss_1st"
MULTILEVEL = ("wavelet_124_coupled", "wavelet_124_perlevel")
ML_LEVELS = (1, 2, 3)
MASS_LOSS = 1
AUX_BEARING_CONTACT = 2
#: closed-loop radius above which a row is reported as marginal (model check)
MARGINAL_RADIUS = 0.95
#: HOLD ramp-to-zero of ``wavelet_reconf_alarm_ramp`` (periods; supervisor module docstring)
HOLD_RAMP_PERIODS = 4
#: +- percent of the early action's bank about each scenario's speed (covers the robustness
#: matrix's +-10 % speed cases; models every 1 %, 25 in all)
EARLY_BAND_PERCENT = 12.0


def at_speed(scenario, speed_hz: float):
    """
    ``scenario`` at another constant speed, its fault at the same angle of the same revolution.

    The first fault's onset and the duration scale with the period, so the run has as many
    revolutions before and after the fault, and the fault falls at the same phase of its
    revolution (the same sample, and the same fraction of it). A speed error then changes the
    rotor's response and the controller's model match, not where in its period the fault
    falls, which alone moves the best achievable peak by a factor of two at the first critical
    speed (``amb-bound``'s phases: 52-103 um at i = 1). At the scenario's own speed nothing
    changes.
    """
    scale = scenario.speed_hz / float(speed_hz)
    moved = replace(scenario, speed_hz=float(speed_hz), duration=scenario.duration * scale)
    fault = first_fault(scenario)
    if fault is None:
        return moved
    events = tuple(replace(e, time=e.time * scale) if e is fault else e for e in scenario.events)
    return replace(moved, events=events)


@dataclass(frozen=True)
class Spec:
    """One controller of the matrix: ControllerConfig fields and the model route."""

    name: str
    controller: str
    delay: int = 1
    model: str = "fe"  # fe | harmonic | trials | none
    output_basis: str = "wavelet"  # ControllerConfig.output_basis
    early: bool = False  # add the early action on a sudden unbalance (amb_controller.early_action)


SPECS = {
    "pid": Spec("pid", "none", 1, "none"),
    "wavelet_i1": Spec("wavelet_i1", "transient", 1, "fe"),
    "wavelet_i2": Spec("wavelet_i2", "transient", 2, "fe"),
    # eq. 8.10 on the Haar coefficients with a 1 x sinusoidal force (issue 18 item 3)
    "wavelet_sin_i1": Spec("wavelet_sin_i1", "transient", 1, "fe", "sinusoid"),
    "wavelet_sin_i2": Spec("wavelet_sin_i2", "transient", 2, "fe", "sinusoid"),
    # receding horizon on the same coefficients and model, sinusoidal force (item 2)
    "predictive_i1": Spec("predictive_i1", "predictive", 1, "fe", "sinusoid"),
    "predictive_i2": Spec("predictive_i2", "predictive", 2, "fe", "sinusoid"),
    # the same with the fault's own period read for a sudden unbalance (item 4)
    "predictive_early_i1": Spec("predictive_early_i1", "predictive", 1, "fe", "sinusoid", True),
    "predictive_early_i2": Spec("predictive_early_i2", "predictive", 2, "fe", "sinusoid", True),
    "harmonic_i1": Spec("harmonic_i1", "harmonic", 1, "harmonic"),
    "synchronous_i1": Spec("synchronous_i1", "synchronous", 1, "trials"),
    # the baselines at the thesis's (and a realtime rig's) delay: every i = 2 row is compared
    # with them, at the same force limit, sensors and delay (issue 18)
    "harmonic_i2": Spec("harmonic_i2", "harmonic", 2, "harmonic"),
    "synchronous_i2": Spec("synchronous_i2", "synchronous", 2, "trials"),
}


class Matrix:
    """
    Rig, scenarios and models shared by the runs (models computed once per speed).

    ``args`` are the constructor's arguments: a worker process of a parallel sweep builds its
    own matrix from them once (:meth:`shared`) and keeps its models for its later runs.
    """

    _shared: ClassVar[dict[tuple, Matrix]] = {}

    @classmethod
    def shared(cls, *args) -> Matrix:
        """Return this process's matrix built from ``args`` (built on the first call)."""
        if args not in cls._shared:
            cls._shared = {args: cls(*args)}
        return cls._shared[args]

    @classmethod
    def adopt(cls, matrix: Matrix) -> None:
        """Make ``matrix`` the one :meth:`shared` returns for its ``args`` in this process."""
        cls._shared = {matrix.args: matrix}

    def __init__(self, scenario_dir: Path, samples_per_rev: int | None, force_limit, quick):
        self.args = (Path(scenario_dir), samples_per_rev, force_limit, bool(quick))
        self.quick = bool(quick)
        self.rig = load_rig()
        self.force_limit = float(force_limit or self.rig.amb.force_limit)
        self.scenarios = {}
        for key, name in SCENARIOS.items():
            sc = load_scenario(scenario_dir / name, self.rig)
            if quick:  # 4 s, or 2 s after a later fault
                fault = max((e.time for e in sc.events), default=0.0)
                sc = replace(sc, duration=min(sc.duration, max(4.0, fault + 2.0)))
            self.scenarios[key] = sc
        self.spr = samples_per_rev
        self._models: dict = {}

    def config(self, spec: Spec, scenario, **overrides):
        """Return the ControllerConfig of ``spec`` for ``scenario``."""
        return ControllerConfig(
            samples_per_rev=self.spr or scenario.samples_per_rev or 64,
            controller=spec.controller,
            delay_periods=spec.delay,
            w=0.75,
            v=0.75,
            gain=0.5,
            inverse_order=5,
            force_limit=(self.force_limit,) * 4,
            output_basis=spec.output_basis,
            **overrides,
        )

    def model(self, spec: Spec, scenario, config, speed_hz: float | None = None):
        """Return (and cache) the model of ``spec`` identified at ``speed_hz``."""
        if spec.model == "none":
            return None
        hz = scenario.speed_hz if speed_hz is None else speed_hz
        key = (
            spec.model,
            round(hz, 6),
            config.samples_per_rev,
            config.delay_periods,
            config.levels,
            config.sensors,
            config.output_basis,
        )
        if key not in self._models:
            omega = 2 * math.pi * hz
            if spec.model == "fe":
                self._models[key] = fe_model(self.rig, omega, config)
            elif spec.model == "harmonic":
                self._models[key] = harmonic_model(self.rig, omega, config)
            else:
                self._models[key] = influence_by_trials(
                    self.rig, replace(scenario, speed_hz=hz), config
                )
        return self._models[key]

    def run(self, spec: Spec, key: str, model=None, speed_hz=None, **kw):
        """Run ``spec`` on scenario ``key``; return the RunResult."""
        scenario = self.scenarios[key]
        config = self.config(spec, scenario)
        if model is None:
            model = self.model(spec, scenario, config)
        if spec.early:  # the models about the scenario's (nominal) speed
            kw.setdefault("early_model", self.early_model(scenario, config))
        if speed_hz is not None:
            scenario = at_speed(scenario, speed_hz)
        return run_closed_loop(self.rig, scenario, config, model, **kw)

    def early_model(self, scenario, config):
        """Return (and cache) the early action's models about ``scenario``'s speed.

        A bank from ``EARLY_BAND_PERCENT`` below to above it (:func:`band_speeds`), as a user
        would make for a rig that runs within that band: the robustness matrix's speed cases
        (+-10 %) find a model there.
        """
        key = ("early", round(scenario.speed_hz, 6), config.samples_per_rev)
        if key not in self._models:
            speeds = band_speeds(scenario.speed_hz, EARLY_BAND_PERCENT)
            self._models[key] = early_action_bank(
                self.rig, scenario, config.samples_per_rev, speeds
            )
        return self._models[key]
