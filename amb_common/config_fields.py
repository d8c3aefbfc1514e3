"""
Configuration fields that carry their own documentation: one home for each fact of a parameter.

A core's configuration dataclass (the controller's ``ControllerConfig``, the fault monitor's
``MonitorConfig``) builds its fields with :func:`param`: the default, a description with its
unit, the allowed values, an optional range and whether the value may change while running sit
together on the field (``dataclasses.field`` metadata). A node declares its ROS parameters from
:func:`parameter_fields` (default from :func:`default_of`, descriptor from the metadata), and
the core, the node and the command lines read the same field. Plain Python: no ROS, no numpy.
"""

from __future__ import annotations

from dataclasses import MISSING, Field, field, fields

__all__ = ["default_of", "param", "parameter_fields"]


def param(
    default=MISSING,
    *,
    description: str,
    allowed: str = "",
    runtime: bool = False,
    parameter: bool = True,
    default_factory=MISSING,
    ints: tuple[int, int] | None = None,
    floats: tuple[float, float] | None = None,
):
    """A dataclass field with its description, allowed range and run-time flag as metadata.

    Parameters
    ----------
    default, default_factory
        As for ``dataclasses.field``.
    description : str
        What the field is, with its unit.
    allowed : str
        The allowed values, as the validation's refusal names them ('' = any of its type).
    runtime : bool
        May change while running (applied by the node); else read-only.
    parameter : bool
        Declared as a ROS parameter by the node (e.g. the controller's fixed ``frames`` is not).
    ints, floats : tuple, optional
        Inclusive ``(low, high)`` range the ROS parameter descriptor enforces itself (None: the
        dataclass's own validation checks the value, and its refusal names the range).
    """
    metadata = {
        "description": description,
        "allowed": allowed,
        "runtime": runtime,
        "parameter": parameter,
        "ints": ints,
        "floats": floats,
    }
    return field(default=default, default_factory=default_factory, metadata=metadata)


def default_of(f: Field):
    """The default value of a dataclass field (calling its ``default_factory`` if it has one)."""
    return f.default_factory() if f.default is MISSING else f.default


def parameter_fields(cls) -> list[Field]:
    """The fields of a dataclass built with :func:`param` that are ROS parameters, in order."""
    return [f for f in fields(cls) if f.metadata.get("parameter", False)]
