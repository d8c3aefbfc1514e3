"""
The ROS parameters of the ``wavelet_controller`` node and their mapping onto the configuration.

The node declares one ROS parameter per field of
:class:`~amb_controller.config.ControllerConfig` and of :class:`NodeSettings` (its own settings:
timeouts, status period, rig file, start mode, model output), each with the descriptor
:func:`parameter_descriptor` builds from the field. A ROS parameter cannot hold inf, an empty
list or a mapping: :func:`parameter_value` gives the ROS form of a field's value and
:func:`config_from_parameters` maps the parameter values back onto the configuration's fields.
:data:`TUNABLES` and :data:`SETTINGS` are those the node accepts at run time (its module notes,
"Parameters"), validated by :func:`runtime_change` as at start-up.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, fields

from rcl_interfaces.msg import ParameterDescriptor

from amb_common.config_fields import param, parameter_fields
from amb_controller.config import ControllerConfig
from amb_controller.errors import ControllerValueError
from amb_tools.node_main import ConfigurationError, field_descriptor

START_MODES = ("off", "active", "identify")


@dataclass(frozen=True)
class NodeSettings:
    """The node's own parameters, beside the controller's (:class:`ControllerConfig`)."""

    measurement_timeout: float = param(
        2.0,
        description="watchdog: wall s without a measurement or coefficient message before "
        "holding zero and reporting",
        runtime=True,
        floats=(0.05, 600.0),
    )
    # 1 s: the restart tests (plant command_timeout 0.5 s) need the controller to answer a
    # missing filterbank quickly. Counted from the later of the sample's measurement and the
    # last coefficient message (amb_controller.node's module notes).
    coefficient_timeout: float = param(
        1.0,
        description="wall s without a coefficient message (and since the sample's measurement) "
        "before a sample is processed without its coefficients",
        runtime=True,
        floats=(0.01, 600.0),
    )
    status_period: float = param(
        1.0,
        description="period of the /diagnostics report, wall s",
        runtime=True,
        floats=(0.05, 60.0),
    )
    rig_file: str = param("", description="rig YAML ('' = package's)")
    start_mode: str = param(
        "off",
        description="off | active | identify (on-line identification from the start, model "
        "written to model_file_out)",
        allowed=f"one of {START_MODES}",
    )
    model_file_out: str = param(
        "", description="where identification writes the model ('' = none)", runtime=True
    )


#: The controller's ROS parameters: the fields of ControllerConfig (all but ``frames``).
PARAMETERS = tuple(f.name for f in parameter_fields(ControllerConfig))
#: Controller parameters that may change at run time (applied at a period boundary).
TUNABLES = tuple(f.name for f in parameter_fields(ControllerConfig) if f.metadata["runtime"])
#: Node settings with a range (s): name -> (lowest, highest).
SETTINGS = {f.name: f.metadata["floats"] for f in fields(NodeSettings) if f.metadata["floats"]}
#: Fields whose inf (off) is 0 as a ROS parameter.
INF_AS_ZERO = ("coefficient_bound", "displacement_bound", "max_model_radius")
#: How a ROS parameter carries the values it cannot hold (inf, an empty list, a dict).
ROS_FORMS = {
    **{name: "as a ROS parameter 0 = off" for name in INF_AS_ZERO},
    "series": "as a ROS parameter [0.0] = unused",
    "fault_actions": "as a ROS parameter 'TYPE:ACTION' strings, e.g. '2:hold'",
}


def parameter_value(name: str, value):
    """A field's value as its ROS parameter (:func:`config_from_parameters` maps it back)."""
    if name in INF_AS_ZERO and math.isinf(value):
        return 0.0
    if name == "series" and not value:
        return [0.0]
    if name == "fault_actions":
        return [f"{code}:{action}" for code, action in value.items()]
    return list(value) if isinstance(value, tuple) else value


def parameter_descriptor(f: dataclasses.Field) -> ParameterDescriptor:
    """The ROS descriptor of a field (:func:`amb_tools.node_main.field_descriptor`).

    With the ROS form of inf, empty and mapping values (:data:`ROS_FORMS`) in its description.
    """
    return field_descriptor(f, ROS_FORMS.get(f.name, ""))


def config_from_parameters(values: dict) -> dict:
    """Map the node's parameter values onto ``ControllerConfig`` fields."""
    d = dict(values)
    for bound in INF_AS_ZERO:
        if d[bound] == 0.0:
            d[bound] = math.inf
    if list(d["series"]) == [0.0]:
        d["series"] = ()
    actions = {}
    for item in d["fault_actions"]:
        code, _, action = str(item).partition(":")
        try:
            actions[int(code)] = action
        except ValueError as exc:
            raise ConfigurationError(
                f"parameter 'fault_actions' entry {item!r}: expected 'TYPE:ACTION', e.g. '2:hold'"
            ) from exc
    d["fault_actions"] = actions
    return d


def runtime_change(
    changes: dict, values: dict, capacity: float
) -> tuple[ControllerConfig | None, str | None]:
    """
    Validate a run-time change of the node's parameters with the start-up validation.

    Parameters
    ----------
    changes : dict
        Parameter name -> new value (lists, not ``array``), as set on the node.
    values : dict
        The current values of the controller's parameters (:data:`PARAMETERS`).
    capacity : float
        The bearings' force capacity, N (``ControllerConfig`` checks ``force_limit`` against it).

    Returns
    -------
    config : ControllerConfig or None
        The configuration with the change, if it changes a controller parameter
        (:data:`TUNABLES`); None if only node settings change.
    reason : str or None
        Why the change is refused (nothing of it is then applied); None if it is accepted.
    """
    for name, (lo, hi) in SETTINGS.items():
        if name in changes:
            value = changes[name]
            if not (isinstance(value, float) and lo <= value <= hi):
                return None, f"parameter '{name}' = {value!r}: expected {lo}..{hi} s"
    tunable = {k: v for k, v in changes.items() if k in TUNABLES}
    if not tunable:
        return None, None
    try:
        config = ControllerConfig.from_dict(config_from_parameters({**values, **tunable}), capacity)
    except (ControllerValueError, ValueError, TypeError) as exc:
        return None, f"parameters {tunable!r} refused: {exc}"
    return config, None
