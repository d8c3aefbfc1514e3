"""The system's names are relative; the helpers of amb_common.topics place them under a namespace.

Issue 15: starting every node in a namespace moves the whole system (``/rig1/amb/...``). The
helpers must give what rclpy resolves (checked against a node's own ``resolve_topic_name``), a
bag's namespace must be found from its topic names, and the run's parameters must reach a node
in any namespace (``amb-run`` writes them under each node's fully qualified name).
"""

from __future__ import annotations

import argparse

import pytest

from amb_apps.run_cli import _set_overrides
from amb_apps.system import NODES, node_name, run_params_document
from amb_common import topics
from amb_common.topics import (
    CLOCK,
    COEFFICIENTS,
    COMMAND,
    DIAGNOSTICS,
    FAULT_EVENTS,
    MEASUREMENT,
    STREAM_TYPES,
    absolute,
    bag_namespace,
    diagnostic_name,
    namespace,
    namespace_of,
    stream_types,
)

OWN_NAMES = [
    MEASUREMENT,
    COEFFICIENTS,
    COMMAND,
    topics.STATUS,
    FAULT_EVENTS,
    topics.INJECT_FAULT,
    topics.SET_MODE,
    topics.START_IDENTIFICATION,
]


def test_the_systems_own_names_are_relative_and_the_ros_wide_ones_absolute() -> None:
    assert all(not n.startswith("/") and n.startswith(topics.PREFIX) for n in OWN_NAMES)
    assert set(STREAM_TYPES) <= set(OWN_NAMES)
    assert DIAGNOSTICS == "/diagnostics" and CLOCK == "/clock"


@pytest.mark.parametrize(
    ("text", "expected"),
    [("", "/"), ("/", "/"), ("rig1", "/rig1"), ("/rig1/", "/rig1"), ("/a/b_2", "/a/b_2")],
)
def test_namespace_is_normalised(text: str, expected: str) -> None:
    assert namespace(text) == expected


@pytest.mark.parametrize("text", ["/1rig", "/rig-1", "/a//b", "~", "/rig 1", "/ä"])
def test_an_invalid_namespace_is_refused_with_the_rule(text: str) -> None:
    with pytest.raises(ValueError, match="letters, digits"):
        namespace(text)


def test_absolute_names_under_a_namespace() -> None:
    assert absolute(MEASUREMENT) == "/amb/measurement"
    assert absolute(MEASUREMENT, "/") == "/amb/measurement"
    assert absolute(COEFFICIENTS, "/rig1") == "/rig1/amb/wavelet/coefficients"
    assert absolute(COMMAND, "rig1/") == "/rig1/amb/control/command"
    assert absolute(FAULT_EVENTS, "/site/rig2") == "/site/rig2/amb/fault/events"
    assert absolute(topics.PREFIX + "*", "/rig1") == "/rig1/amb/*"  # a recorder pattern
    assert absolute(DIAGNOSTICS, "/rig1") == "/diagnostics"  # absolute stays
    assert absolute("/amb/measurement", "/rig1") == "/amb/measurement"
    assert stream_types("/rig1") == {
        "/rig1/amb/measurement": "amb_msgs/msg/Measurement",
        "/rig1/amb/wavelet/coefficients": "amb_msgs/msg/WaveletCoefficients",
        "/rig1/amb/control/command": "amb_msgs/msg/ControlCommand",
        "/rig1/amb/control/status": "amb_msgs/msg/ControllerStatus",
        "/rig1/amb/fault/events": "amb_msgs/msg/FaultEvent",
    }
    assert list(stream_types()) == ["/" + t for t in STREAM_TYPES]


def test_namespace_of_a_topic() -> None:
    assert namespace_of("/amb/measurement") == "/"
    assert namespace_of("/rig1/amb/measurement") == "/rig1"
    assert namespace_of("/a/b/amb/wavelet/coefficients", COEFFICIENTS) == "/a/b"
    assert namespace_of("/rig1/amb/measurement", COEFFICIENTS) is None
    assert namespace_of("/rig1/xamb/measurement") is None  # a whole token, not a suffix
    assert namespace_of("/diagnostics") is None


def test_the_namespace_of_a_bag_is_the_one_its_streams_are_under() -> None:
    assert bag_namespace(["/amb/measurement", "/diagnostics", "/amb/control/command"]) == "/"
    assert bag_namespace(["/diagnostics", "/rig1/amb/measurement", "/rig1/amb/fault/events"]) == (
        "/rig1"
    )
    # no measurements: the first stream there decides
    assert bag_namespace(["/r/amb/wavelet/coefficients", "/r/amb/control/command"]) == "/r"
    # nothing of the system: the root, every stream missing
    assert bag_namespace(["/diagnostics"]) == "/"
    assert bag_namespace([]) == "/"
    with pytest.raises(ValueError, match=r"2 namespaces \['/rig1', '/rig2'\]"):
        bag_namespace(["/rig1/amb/measurement", "/rig2/amb/measurement"])


def test_diagnostic_names_carry_the_namespace() -> None:
    assert diagnostic_name("plant_sim") == "plant_sim"
    assert diagnostic_name("plant_sim", "/") == "plant_sim"
    assert diagnostic_name("plant_sim", "/rig1") == "rig1/plant_sim"
    assert diagnostic_name("fault_monitor: plane 2", "/a/b") == "a/b/fault_monitor: plane 2"


@pytest.mark.ros
@pytest.mark.parametrize("ns", ["/", "/rig_a", "/site/rig_b"])
def test_absolute_is_what_rclpy_resolves_in_the_namespace(ros, ns: str) -> None:
    node = ros.node("amb_test_names", namespace=ns)
    for name in [*OWN_NAMES, DIAGNOSTICS, CLOCK]:
        assert node.resolve_topic_name(name) == absolute(name, ns), name
    for name in (topics.INJECT_FAULT, topics.SET_MODE, topics.START_IDENTIFICATION):
        assert node.resolve_service_name(name) == absolute(name, ns), name
    assert node.get_fully_qualified_name() == node_name("amb_test_names", ns)


def test_run_parameters_are_keyed_by_the_fully_qualified_node_name() -> None:
    params = {"plant_sim": {"mode": "realtime", "samples_per_rev": 32}, "recorder": {}}
    assert run_params_document(params) == {
        "/plant_sim": {"ros__parameters": {"mode": "realtime", "samples_per_rev": 32}}
    }
    assert list(run_params_document(params, "/rig1")) == ["/rig1/plant_sim"]


def test_amb_run_set_values_are_read_as_yaml() -> None:
    args = argparse.Namespace(
        set=[
            "wavelet_controller.w:=0.65",
            "wavelet_filterbank.wavelet:=db4",
            "wavelet_filterbank.frames:=[fixed]",
            "plant_sim.exit_at_end:=true",
            "plant_sim.seed:=3",
        ]
    )
    over = _set_overrides(args)
    assert set(over) == set(NODES)
    assert over["wavelet_controller"] == {"w": 0.65}
    assert over["wavelet_filterbank"] == {"wavelet": "db4", "frames": ["fixed"]}
    assert over["plant_sim"] == {"exit_at_end": True, "seed": 3}
    with pytest.raises(SystemExit, match=r"NODE\.PARAM:=VALUE"):
        _set_overrides(argparse.Namespace(set=["plant_sim.seed=3"]))
