"""
The ROS parameters of the ``fault_monitor`` node and the check of a run-time change.

The node declares one ROS parameter per field of :class:`~amb_fault_monitor.config.MonitorConfig`
that is a parameter (:func:`~amb_common.config_fields.parameter_fields`: default, description
with unit, range and run-time flag are the field's) and one per field of :class:`NodeSettings`,
its own settings (trip levels, status period, files, black box), each with the descriptor
:func:`parameter_descriptor` builds from the field. :func:`parameter_value` gives the ROS form of
a field's default (a ROS parameter cannot hold an empty list); the node maps the values back
onto ``MonitorConfig`` by field name. :data:`RUNTIME` names the parameters the on-set callback
accepts, and :func:`check_runtime_value` gives the reason it refuses a value (the node's module
notes, "Parameters").
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from rcl_interfaces.msg import ParameterDescriptor

from amb_common.config_fields import default_of, param, parameter_fields
from amb_fault_monitor.config import MonitorConfig
from amb_tools.node_main import field_descriptor

#: The node's ``samples_per_rev`` when no params file sets it (``MonitorConfig`` has no default:
#: a monitor must be told its stream's).
SAMPLES_PER_REV = 32


@dataclass(frozen=True)
class NodeSettings:
    """The node's own parameters, beside the monitor's (:class:`MonitorConfig`)."""

    trip_displacement: float = param(
        0.0,
        description="radial trip level, m (0 = from the rig clearances)",
        floats=(0.0, 0.1),
        runtime=True,
    )
    trip_displacement_fraction: float = param(
        2.0 / 3.0,
        description="default radial trip level as a share of the nearest clearance",
        floats=(0.01, 1.0),
        runtime=True,
    )
    trip_1x: float = param(
        0.0,
        description="1 x orbit semi-major axis trip level, m (0 = from the rig)",
        floats=(0.0, 0.1),
        runtime=True,
    )
    trip_1x_fraction: float = param(
        0.5,
        description="default 1 x trip level as a share of the nearest clearance",
        floats=(0.01, 1.0),
        runtime=True,
    )
    trip_hysteresis: float = param(
        0.1, description="trip clears below level * (1 - this)", floats=(0.0, 0.99), runtime=True
    )
    status_period: float = param(
        1.0,
        description="period of the /diagnostics report, s (wall clock)",
        floats=(0.05, 60.0),
        runtime=True,
    )
    blackbox_pre_s: float = param(
        2.0, description="black box: seconds kept before an event", floats=(0.0, 600.0)
    )
    blackbox_post_s: float = param(
        1.0, description="black box: seconds recorded after an event", floats=(0.0, 600.0)
    )
    event_log: str = param("", description="JSON-lines event log path ('' = off)")
    rig: str = param("", description="rig file for the clearances ('' = config/rig.yaml)")
    blackbox_dir: str = param("", description="folder of the per-event black-box bags ('' = off)")


#: The monitor's ROS parameters: the parameter fields of MonitorConfig, in order.
MONITOR_PARAMETERS = tuple(parameter_fields(MonitorConfig))
#: The node's own: the fields of NodeSettings, in order.
NODE_PARAMETERS = tuple(parameter_fields(NodeSettings))
#: How a ROS parameter carries the values it cannot hold (an empty list).
ROS_FORMS = {"levels": "[0] = all received"}
_RUNTIME_FIELDS = {
    f.name: f for f in (*MONITOR_PARAMETERS, *NODE_PARAMETERS) if f.metadata["runtime"]
}
#: Parameters the on-set callback accepts (all others are read-only).
RUNTIME = tuple(_RUNTIME_FIELDS)
#: Of those, the MonitorConfig fields (applied to the running monitor's configuration).
MONITOR_RUNTIME = tuple(f.name for f in MONITOR_PARAMETERS if f.metadata["runtime"])


def parameter_value(f: dataclasses.Field):
    """The ROS parameter default of a field: its default in ROS form (``levels`` () is [0])."""
    if f.name == "samples_per_rev":
        return SAMPLES_PER_REV
    value = default_of(f)
    if f.name == "levels" and not value:
        return [0]
    return list(value) if isinstance(value, tuple) else value


def parameter_descriptor(f: dataclasses.Field) -> ParameterDescriptor:
    """The ROS descriptor of a field (:func:`amb_tools.node_main.field_descriptor`)."""
    return field_descriptor(f, ROS_FORMS.get(f.name, ""))


def check_runtime_value(name: str, value: object) -> str | None:
    """Return why a run-time value of parameter ``name`` is refused, or None if it is valid."""
    meta = _RUNTIME_FIELDS[name].metadata
    lo, hi = meta["floats"]
    if not (isinstance(value, float) and math.isfinite(value) and lo <= value <= hi):
        return f"parameter '{name}' = {value!r}: expected {lo:g}..{hi:g} ({meta['description']})"
    return None
