"""
The ROS parameters of the ``plant_sim`` node, and the run they configure.

:class:`PlantSettings` holds every parameter once, as a :func:`~amb_common.config_fields.param`
field (default, description with unit, range, run-time flag); the node declares one ROS
parameter per field (:func:`declare`), reads them back (:func:`settings`) and builds the
checked run from them (:func:`configure`: the rig, the scenario, the sampling and the
simulator), so that a bad value is refused at start with the parameter's name and the reason.
What each mode and rule means is in :mod:`amb_plant_sim.node`.
"""

from __future__ import annotations

from dataclasses import dataclass

from rclpy.node import Node

from amb_common import topics
from amb_common.config_fields import default_of, param, parameter_fields
from amb_common.errors import RigError
from amb_common.paths import config_file, scenario_file
from amb_common.rig import Rig, load_rig
from amb_plant_sim.errors import ScenarioError, SimulationError
from amb_plant_sim.scenario import Scenario, load_scenario, resolve_samples_per_rev
from amb_plant_sim.simulator import PlantSimulator
from amb_tools.node_main import ConfigurationError, field_descriptor

MODES = ("lockstep", "realtime")


@dataclass(frozen=True)
class PlantSettings:
    """The node's parameters (module docstring); the run-time ones apply at a period boundary."""

    rig_file: str = param("", description="rig description YAML ('' = the package's rig.yaml)")
    scenario_file: str = param("", description="scenario YAML: speed, duration, events (required)")
    samples_per_rev: int = param(
        0, description="samples per revolution, power of two (0 = scenario's)", ints=(0, 4096)
    )
    samples_per_period: int = param(
        0, description="control period in samples (0 = samples_per_rev)", ints=(0, 65536)
    )
    mode: str = param("lockstep", description="who owns time", allowed=" | ".join(MODES))
    delay_periods: int = param(
        topics.DELAY_PERIODS,
        description="i: commands for period k answer measured period k - i",
        ints=(1, 16),
    )
    command_timeout: float = param(
        5.0,
        description="lockstep: wall s to wait for a command before running the period without it",
        runtime=True,
        floats=(0.01, 600.0),
    )
    wait_for_subscribers: int = param(
        1, description="subscribers of /amb/measurement to wait for before sample 0", ints=(0, 64)
    )
    startup_timeout: float = param(30.0, description="wall s to wait for them", floats=(0.0, 600.0))
    time_scale: float = param(
        1.0, description="realtime: simulated s per wall s", runtime=True, floats=(0.01, 100.0)
    )
    wavelet_force_limit: float = param(
        0.0,
        description="N per axis (0 = the rig's bearing capacity)",
        runtime=True,
        floats=(0.0, 1.0e5),
    )
    partial_commands: bool = param(
        True,
        description="realtime: apply a command that arrives during its period to the samples "
        "still ahead (counted partial and late)",
    )
    seed: int = param(0, description="noise seed", ints=(0, 2**31 - 1))
    exit_at_end: bool = param(True, description="exit when the scenario duration is reached")
    clock_every: int = param(
        8, description="publish /clock every this many samples", ints=(1, 65536)
    )
    status_period: float = param(
        1.0,
        description="period of the /diagnostics report, wall s",
        runtime=True,
        floats=(0.05, 60.0),
    )


#: Parameters settable at run time (applied at the next period boundary).
RUNTIME_PARAMETERS = tuple(f.name for f in parameter_fields(PlantSettings) if f.metadata["runtime"])


@dataclass(frozen=True)
class PlantRun:
    """The run the parameters configure (checked)."""

    settings: PlantSettings
    rig: Rig
    scenario: Scenario
    #: Samples per revolution (a power of two >= 4).
    samples_per_rev: int
    #: Samples per control period (divides or is a multiple of ``samples_per_rev``).
    samples_per_period: int
    #: Wavelet force limit per axis, N (at most the bearing capacity).
    force_limit: float
    simulator: PlantSimulator
    #: Samples of the run: whole control periods, as many as fit the duration (rounded; amb-sim
    #: runs the same); None for a speed profile (the run ends at the duration).
    n_total: int | None


def declare(node: Node) -> None:
    """Declare every parameter of :class:`PlantSettings` on ``node``, with its descriptor."""
    for f in parameter_fields(PlantSettings):
        node.declare_parameter(f.name, default_of(f), field_descriptor(f))


def settings(node: Node) -> PlantSettings:
    """The node's parameter values."""
    return PlantSettings(
        **{f.name: node.get_parameter(f.name).value for f in parameter_fields(PlantSettings)}
    )


def configure(s: PlantSettings) -> PlantRun:
    """Load the rig and scenario, check the sampling and limits, build the simulator.

    Raises
    ------
    ConfigurationError
        Naming the parameter and why its value cannot run.
    """
    rig_file = s.rig_file or str(config_file("rig.yaml"))
    try:
        rig = load_rig(rig_file)
    except RigError as exc:
        raise ConfigurationError(f"parameter 'rig_file' = {rig_file!r}: {exc}") from exc
    if not s.scenario_file:
        raise ConfigurationError("parameter 'scenario_file' is empty: name a scenario YAML")
    try:
        path = scenario_file(s.scenario_file)
    except FileNotFoundError as exc:
        raise ConfigurationError(
            f"parameter 'scenario_file' = {s.scenario_file!r}: no such file"
        ) from exc
    try:
        scenario = load_scenario(path, rig)
    except ScenarioError as exc:
        raise ConfigurationError(f"parameter 'scenario_file' = {str(path)!r}: {exc}") from exc
    spr = resolve_samples_per_rev(s.samples_per_rev, scenario)
    if spr < 4 or spr & (spr - 1):
        raise ConfigurationError(
            f"parameter 'samples_per_rev' = {spr}: must be a power of two >= 4"
        )
    n = s.samples_per_period or spr
    if n % spr and spr % n:
        raise ConfigurationError(
            f"parameter 'samples_per_period' = {n}: must divide or be a multiple of "
            f"samples_per_rev = {spr}"
        )
    if s.mode not in MODES:
        raise ConfigurationError(f"parameter 'mode' = {s.mode!r}: allowed {MODES}")
    limit = s.wavelet_force_limit or rig.amb.force_limit
    if limit > rig.amb.force_limit:
        raise ConfigurationError(
            f"parameter 'wavelet_force_limit' = {limit} N exceeds the bearing capacity "
            f"{rig.amb.force_limit} N (rig file amb.force_limit)"
        )
    try:
        sim = PlantSimulator(rig, scenario, samples_per_rev=spr, seed=s.seed)
    except SimulationError as exc:
        raise ConfigurationError(str(exc)) from exc
    periods = max(1, round(scenario.duration * sim.fs / n))
    return PlantRun(
        settings=s,
        rig=rig,
        scenario=scenario,
        samples_per_rev=spr,
        samples_per_period=n,
        force_limit=limit,
        simulator=sim,
        n_total=periods * n if not scenario.profile_hz else None,
    )
