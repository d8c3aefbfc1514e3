"""Run-time changes of the controller node's parameters, validated as at start-up (no ROS)."""

from __future__ import annotations

import pytest

from amb_common.config_fields import default_of, parameter_fields
from amb_common.paths import config_file
from amb_common.rig import load_rig
from amb_controller.config import ControllerConfig
from amb_controller.node_params import parameter_value, runtime_change

#: The node's start-up values of the controller's parameters (their ROS forms).
STARTUP = {
    f.name: parameter_value(f.name, default_of(f)) for f in parameter_fields(ControllerConfig)
}


@pytest.fixture(scope="module")
def capacity() -> float:
    """The bearings' force capacity of the package's rig, N."""
    return load_rig(config_file("rig.yaml")).amb.force_limit


def test_a_tunable_change_gives_the_new_configuration(capacity) -> None:
    config, reason = runtime_change({"gain": 0.35, "rate": 0.5}, STARTUP, capacity)
    assert reason is None
    assert (config.gain, config.rate) == (0.35, 0.5)
    assert config.wavelet == STARTUP["wavelet"]  # the rest as it was


def test_node_settings_alone_give_no_configuration(capacity) -> None:
    assert runtime_change({"status_period": 0.5}, STARTUP, capacity) == (None, None)


@pytest.mark.parametrize(
    ("changes", "named"),
    [
        ({"measurement_timeout": 0.0}, "measurement_timeout"),  # no watchdog at all
        ({"coefficient_timeout": 601.0}, "coefficient_timeout"),  # beyond ten minutes
        ({"status_period": 1}, "status_period"),  # an integer: the parameter is a double
        ({"gain": -0.2}, "gain"),  # a negative gain
        ({"rate": 1.0}, "rate"),  # a response that never decays
    ],
)
def test_bad_changes_are_refused_with_the_parameter_named(changes, named, capacity) -> None:
    config, reason = runtime_change(changes, STARTUP, capacity)
    assert config is None
    assert named in reason


def test_a_force_limit_beyond_the_bearings_is_refused(capacity) -> None:
    over = [capacity * 1.5] * 4
    config, reason = runtime_change({"force_limit": over}, STARTUP, capacity)
    assert config is None and "force_limit" in reason
    config, reason = runtime_change({"force_limit": [capacity / 2] * 4}, STARTUP, capacity)
    assert reason is None and config.force_limit == (capacity / 2,) * 4
