"""
Topic and service names, each stream's message type, and the exchange's default delay.

One home for the names of ARCHITECTURE.md's topic table: every node, the replay bridge, the
recorder, the in-process loop's bag, ``amb-run`` and the bag reader take them from here. So
does :data:`DELAY_PERIODS`, the default delay both ends of ``amb/control/command`` must agree
on (the plant refuses a command made for another delay).

The system's own names are **relative** (``amb/measurement``): a node resolves them against its
namespace, so that starting every node with one (``--ros-args -r __ns:=/rig1``, the launch
file's ``namespace:=/rig1``, ``amb-run --namespace /rig1``) moves the whole system to
``/rig1/amb/...`` and two systems run side by side without crosstalk. Started without a
namespace (``/``) the names are the ``/amb/...`` ones. ``/diagnostics`` and ``/clock`` are
ROS-wide and stay absolute. :func:`absolute` gives a name's absolute form under a namespace
(what a bag holds); :func:`bag_namespace` finds the namespace a bag was recorded under.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

__all__ = [
    "CLOCK",
    "COEFFICIENTS",
    "COMMAND",
    "DELAY_PERIODS",
    "DIAGNOSTICS",
    "FAULT_EVENTS",
    "INJECT_FAULT",
    "MEASUREMENT",
    "PREFIX",
    "ROOT_NAMESPACE",
    "SAMPLES_PER_COEFFICIENT_MESSAGE",
    "SET_MODE",
    "START_IDENTIFICATION",
    "STATUS",
    "STREAM_TYPES",
    "absolute",
    "bag_namespace",
    "diagnostic_name",
    "namespace",
    "namespace_of",
    "stream_types",
]

#: The namespace of a system started without one.
ROOT_NAMESPACE = "/"
#: Prefix of the system's own topics, relative (the recorder's default pattern is
#: ``PREFIX + "*"``, resolved against its namespace).
PREFIX = "amb/"
#: One sample of the rig: displacements, currents, forces, angle, speed (plant or bridge).
MEASUREMENT = "amb/measurement"
#: The filterbank's wavelet coefficients of the measurement stream.
COEFFICIENTS = "amb/wavelet/coefficients"
#: Samples per coefficient message: the filterbank publishes when its finest level (decimated by
#: two) completes a coefficient, every second sample (thesis section 4.3).
SAMPLES_PER_COEFFICIENT_MESSAGE = 2
#: The controller's wavelet force for one control period.
COMMAND = "amb/control/command"
#: The controller's state, once a period.
STATUS = "amb/control/status"
#: The fault monitor's classified events.
FAULT_EVENTS = "amb/fault/events"
#: Every node's health report (ROS-wide: absolute).
DIAGNOSTICS = "/diagnostics"
#: Simulated time (plant_sim; ROS-wide: absolute).
CLOCK = "/clock"
#: Services.
INJECT_FAULT = "amb/plant/inject_fault"
SET_MODE = "amb/control/set_mode"
START_IDENTIFICATION = "amb/control/start_identification"

#: Default control delay i in periods (thesis section 8.5.1: "the controller evaluation time
#: required there to be a 2 cycle delay in control action"): the command computed from measured
#: period k is applied in period k + i. Default of ``ControllerConfig.delay_periods`` and of the
#: plant's ``delay_periods`` parameter; ``config/amb_params.yaml`` sets both nodes under ``/**``.
DELAY_PERIODS: int = 2

#: The streams a run's bag holds (relative names: :func:`stream_types` gives them under a
#: namespace), with their rosbag2 message types.
STREAM_TYPES = {
    MEASUREMENT: "amb_msgs/msg/Measurement",
    COEFFICIENTS: "amb_msgs/msg/WaveletCoefficients",
    COMMAND: "amb_msgs/msg/ControlCommand",
    STATUS: "amb_msgs/msg/ControllerStatus",
    FAULT_EVENTS: "amb_msgs/msg/FaultEvent",
}


#: A namespace: ``/`` or ``/token[/token...]``, tokens of letters, digits and ``_``, not starting
#: with a digit (the ROS rules for a fully qualified namespace).
_NAMESPACE = re.compile(r"/|(/[A-Za-z_][A-Za-z0-9_]*)+")


def namespace(text: str = ROOT_NAMESPACE) -> str:
    """Return ``text`` as a fully qualified namespace (``""`` is ``/``, ``rig1/`` is ``/rig1``).

    Raises
    ------
    ValueError
        If ``text`` is not a valid ROS namespace (``~``, ``//``, a token starting with a digit,
        characters other than letters, digits, ``_`` and ``/``).
    """
    ns = "/" + text.strip().strip("/")
    if not _NAMESPACE.fullmatch(ns):
        raise ValueError(
            f"namespace {text!r}: expected '/' or '/name[/name...]' (letters, digits, '_'; "
            "a name does not start with a digit)"
        )
    return ns


def absolute(name: str, ns: str = ROOT_NAMESPACE) -> str:
    """Return the absolute name of ``name`` under namespace ``ns``.

    ``absolute(MEASUREMENT)`` is ``/amb/measurement``, ``absolute(MEASUREMENT, "/rig1")`` is
    ``/rig1/amb/measurement`` (what a node in ``/rig1`` resolves it to, and what a bag recorded
    under ``/rig1`` holds); an absolute name (``/diagnostics``) is returned unchanged.
    """
    if name.startswith("/"):
        return name
    ns = namespace(ns)
    return f"{ns.rstrip('/')}/{name}"


def namespace_of(topic: str, name: str = MEASUREMENT) -> str | None:
    """Return the namespace under which absolute ``topic`` is the relative ``name``, or None.

    ``namespace_of("/rig1/amb/measurement")`` is ``/rig1``; ``namespace_of("/amb/measurement")``
    is ``/``; ``namespace_of("/amb/other")`` is None.
    """
    suffix = "/" + name
    if not topic.endswith(suffix):
        return None
    try:
        return namespace(topic[: -len(suffix)])
    except ValueError:
        return None


def bag_namespace(topic_names: Iterable[str]) -> str:
    """Return the namespace a bag's streams were recorded under, from its topic names.

    The namespace is the one prefix under which the measurement topic is found; in a bag
    without measurements, the one under which the first stream of :data:`STREAM_TYPES` that is
    there is found. A bag holding none of the streams reads as the root namespace (every stream
    then missing).

    Raises
    ------
    ValueError
        If the stream is found under more than one namespace (two systems in one bag): name the
        one to read (``read_bag(..., namespace=)``, ``amb-report --namespace``).
    """
    names = list(topic_names)
    for stream in STREAM_TYPES:
        found = sorted({ns for t in names if (ns := namespace_of(t, stream)) is not None})
        if len(found) == 1:
            return found[0]
        if found:
            raise ValueError(
                f"{stream} is in the bag under {len(found)} namespaces {found}: "
                "say which one to read (read_bag(..., namespace=), amb-report --namespace)"
            )
    return ROOT_NAMESPACE


def stream_types(ns: str = ROOT_NAMESPACE) -> dict[str, str]:
    """Return :data:`STREAM_TYPES` with the absolute topic names under namespace ``ns``."""
    return {absolute(t, ns): m for t, m in STREAM_TYPES.items()}


def diagnostic_name(name: str, ns: str = ROOT_NAMESPACE) -> str:
    """Return the ``DiagnosticStatus.name`` a node reports under on ``/diagnostics``.

    ``/diagnostics`` is ROS-wide: two systems in two namespaces report on the same topic, so a
    node names its status with its namespace (``rig1/plant_sim``; ``plant_sim`` at the root,
    ``rig1/fault_monitor: plane 1``), which keeps ``amb-run``'s progress and drain of one
    system apart from the other's.
    """
    ns = namespace(ns)
    return name if ns == ROOT_NAMESPACE else f"{ns.strip('/')}/{name}"
