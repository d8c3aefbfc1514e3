"""Scenario files and events: loading, speed roles resolved from the model, validation."""

import pytest

from amb_common.errors import RigError
from amb_common.rig import load_rig, rig_from_dict
from amb_plant_sim.errors import ScenarioError
from amb_plant_sim.events import event_from_dict
from amb_plant_sim.modal import critical_speeds
from amb_plant_sim.scenario import load_scenario, scenario_from_dict

from .conftest import RIG_PATH

SCENARIOS = sorted((RIG_PATH.parent / "scenarios").glob("*.yaml"))


@pytest.fixture(scope="module")
def crit(rig):
    return critical_speeds(rig, 4)


def test_critical_speeds_are_near_the_calibrated_frequencies(rig, crit):
    # forward whirl crossings of the synchronous line: close to the zero-speed frequencies
    for c, f0 in zip(crit, rig.calibration["achieved_hz"], strict=True):
        assert c == pytest.approx(f0, rel=0.06)
    assert crit == sorted(crit)


@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.stem)
def test_example_scenarios_load_and_resolve(rig, crit, path):
    load_scenario(path)  # loads without a model too
    sc = load_scenario(path, rig, crit)
    assert sc.duration > 0 and sc.speed_hz > 0
    if sc.speed.role is not None:
        roles = ("first_critical", "second_critical", "third_critical", "fourth_critical")
        assert sc.speed_hz == pytest.approx(crit[roles.index(sc.speed.role)])


def test_mass_loss_scenario_is_the_thesis_test(rig, crit):
    sc = load_scenario(RIG_PATH.parent / "scenarios" / "mass_loss_first_critical.yaml", rig, crit)
    ml = [e for e in sc.events if e.kind == "mass_loss"]
    assert len(ml) == 1
    assert ml[0].get("me") == pytest.approx(430e-3 * 1e-2)  # 430 g cm in kg m
    assert ml[0].get("disk") == rig.disks[0].tag  # the non-driven-end disk
    assert max(d.z for d in rig.disks) == rig.disks[0].z
    assert sc.speed_hz == pytest.approx(crit[0])


def test_speed_by_value_needs_no_model():
    sc = scenario_from_dict({"speed": {"hz": 22.0}, "duration": 1.0})
    assert sc.speed_hz is None and sc.speed.hz == 22.0


@pytest.mark.parametrize(
    "bad,match",
    [
        ({"speed": {"role": "fifth_critical"}, "duration": 1.0}, "unknown role"),
        ({"speed": {"hz": -3.0}, "duration": 1.0}, "> 0 Hz"),
        ({"speed": {"hz": 3.0}, "duration": 0.0}, "duration"),
        ({"speed": {"hz": 3.0}, "duration": 1.0, "samples_per_rev": 48}, "power of two"),
        ({"duration": 1.0}, "speed"),
    ],
)
def test_invalid_scenarios_are_refused(bad, match):
    with pytest.raises(ScenarioError, match=match):
        scenario_from_dict(bad)


@pytest.mark.parametrize(
    "bad,match",
    [
        ({"kind": "mass_loss", "me": 1e-3}, "disk"),
        ({"kind": "mass_loss", "disk": "D1"}, "missing"),
        ({"kind": "sync_force", "bearing": 3, "amplitude": 1.0}, "bearing must be 1 or 2"),
        ({"kind": "sensor_fault", "plane": 5, "axis": "x", "mode": "zero"}, "plane"),
        ({"kind": "sensor_fault", "plane": 1, "axis": "x", "mode": "melted"}, "mode"),
        ({"kind": "amb_channel_loss", "axis": "b3x"}, "axis"),
        ({"kind": "unbalance", "disk": "D1", "me": 1e-3, "colour": 2}, "unknown field"),
    ],
)
def test_invalid_events_are_refused(bad, match):
    with pytest.raises(ScenarioError, match=match):
        event_from_dict(bad)


def test_rig_validation_messages():
    import yaml

    data = yaml.safe_load(RIG_PATH.read_text())
    data["shaft"]["elements"] = 5
    with pytest.raises(RigError, match="raise it"):
        rig_from_dict(data)
    data = yaml.safe_load(RIG_PATH.read_text())
    data["pid"]["Kp"] = -1.0
    with pytest.raises(RigError, match=r"pid\.Kp"):
        rig_from_dict(data)
    data = yaml.safe_load(RIG_PATH.read_text())
    data["amb"]["peak_voltage"] = 3.0  # below the coil's 0.365 ohm x 10 A
    with pytest.raises(RigError, match="peak_voltage"):
        rig_from_dict(data)
    with pytest.raises(RigError, match="not found"):
        load_rig("/nonexistent/rig.yaml")


@pytest.mark.parametrize(
    ("section", "key"),
    [
        ("amb", "force_limit"),
        ("amb", "turns"),
        ("amb", "peak_voltage"),
        ("amb", "law"),
        ("contact", "substeps"),
        ("contact", "rotor_radius"),
        ("shaft", "shear"),
        ("simulation", "internal_rate_min"),
        (None, "contact"),
        (None, "simulation"),
    ],
)
def test_a_missing_rig_number_is_an_error_naming_it(section, key):
    """The rig's numbers live in the rig file only: none is filled in by the code."""
    import yaml

    data = yaml.safe_load(RIG_PATH.read_text())
    del (data[section] if section else data)[key]
    with pytest.raises(RigError, match=f"missing key '{key}' in {section or 'top level'}"):
        rig_from_dict(data)


@pytest.mark.parametrize(
    ("text", "words"),
    [("shaft: [unclosed\n", "not readable YAML"), ("- just\n- a list\n", "expected a mapping")],
)
def test_malformed_rig_file_raises_rig_error(tmp_path, text, words):
    # A malformed file must surface as RigError (the nodes turn it into exit code 2), not as
    # the YAML parser's own exception.
    bad = tmp_path / "rig.yaml"
    bad.write_text(text)
    with pytest.raises(RigError, match=words):
        load_rig(bad)


def test_a_malformed_scenario_file_is_a_scenario_error(tmp_path):
    bad = tmp_path / "scenario.yaml"
    bad.write_text("speed: {hz: [unclosed\n")
    with pytest.raises(ScenarioError, match="not readable YAML"):
        load_scenario(bad)
