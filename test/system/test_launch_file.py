"""The launch file and amb-run start the same node set with the same per-run parameters.

The launch file is not runnable here (launch is not on PyPI): it is parsed, and the function it
builds its nodes with, :func:`amb_apps.system.run_parameters`, which ``amb-run`` uses too, is
tested. Every node it starts is a console script of ``setup.py``, every parameter it sets is
one the node declares, every launch argument has a description, and a scenario's
``samples_per_rev`` reaches every sampling node (``ros2 launch`` once ran the 32-sample fault
scenarios at the params file's 64).
"""

from __future__ import annotations

import ast
import re
from dataclasses import fields
from pathlib import Path

import pytest

from amb_apps.system import NODES, run_parameters, stream_readers
from amb_common import topics
from amb_common.paths import scenario_file
from amb_plant_sim.errors import ScenarioError
from amb_tools.backlog import BY_AGE, MAX_BACKLOG

ROOT = Path(__file__).resolve().parents[2]
LAUNCH = ROOT / "launch" / "amb_system.launch.py"
NODE_MODULES = {
    "plant_sim": "amb_plant_sim/node.py",
    "wavelet_filterbank": "amb_wavelet/node.py",
    "fault_monitor": "amb_fault_monitor/node.py",
    "wavelet_controller": "amb_controller/node.py",
    "recorder": "amb_tools/recorder_node.py",
}


def _launch_tree() -> ast.Module:
    return ast.parse(LAUNCH.read_text())


def test_launch_builds_its_nodes_with_run_parameters() -> None:
    tree = _launch_tree()
    called = {getattr(c.func, "id", None) for c in ast.walk(tree) if isinstance(c, ast.Call)}
    assert {"run_parameters", "Node", "OpaqueFunction"} <= called
    imported = {
        a.name
        for n in ast.walk(tree)
        if isinstance(n, ast.ImportFrom) and n.module == "amb_apps.system"
        for a in n.names
    }
    assert {"NODES", "run_parameters"} <= imported
    # every node gets the namespace (so launch_ros keys the run's parameters by its full name)
    nodes = [
        c for c in ast.walk(tree) if isinstance(c, ast.Call) and getattr(c.func, "id", "") == "Node"
    ]
    assert len(nodes) == 2  # one per node; wavelet_stack for composed:=true
    assert all("namespace" in {k.arg for k in node.keywords} for node in nodes)
    executables = {
        k.value.value for n in nodes for k in n.keywords if k.arg == "executable"
        if isinstance(k.value, ast.Constant)
    }  # fmt: skip
    assert executables == {"wavelet_stack"}  # the other is the loop variable `name`
    # the processes amb-run runs off shared memory get AMB_TRANSPORT from the same list
    assert "OFF_SHARED_MEMORY" in imported
    per_node = [n for n in nodes if "additional_env" in {k.arg for k in n.keywords}]
    assert len(per_node) == 1, "the per-node Node sets additional_env"


def test_every_launch_argument_has_a_description() -> None:
    for node in ast.walk(_launch_tree()):
        if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "ARGUMENTS":
            arguments = ast.literal_eval(node.value)
            break
    else:
        pytest.fail("no ARGUMENTS table in the launch file")
    names = [a[0] for a in arguments]
    assert {
        "scenario", "controller", "start_mode", "model_file", "params", "bag", "mode", "namespace"
    } <= set(names)  # fmt: skip
    for name, default, description in arguments:
        assert isinstance(default, str) and len(description) > 10, name


def test_the_nodes_are_installed_console_scripts() -> None:
    setup = (ROOT / "setup.py").read_text()
    assert set(NODES) == set(NODE_MODULES)
    for name in NODES:
        assert f'"{name}": "' in setup, f"{name} is not a console script in setup.py"


def _declared(name: str) -> set[str] | None:
    """The controller's, the fault monitor's and the plant's parameters as they declare them
    (from their config classes); None: read the other nodes' sources."""
    if name == "wavelet_controller":
        from amb_controller.node_params import PARAMETERS, NodeSettings

        return {*PARAMETERS, *(f.name for f in fields(NodeSettings))}
    if name == "fault_monitor":
        from amb_fault_monitor.node_params import MONITOR_PARAMETERS, NODE_PARAMETERS

        return {f.name for f in (*MONITOR_PARAMETERS, *NODE_PARAMETERS)}
    if name == "plant_sim":
        from amb_plant_sim.node_params import PlantSettings

        return {f.name for f in fields(PlantSettings)}
    return None


def test_run_parameters_are_declared_by_the_nodes() -> None:
    overrides = run_parameters(
        scenario_file("contact_misalignment_second_bending.yaml"),
        controller="transient",
        start_mode="active",
        model_file="/tmp/m.npz",
        model_file_out="/tmp/out.npz",
        mode="realtime",
        bag="/tmp/bag",
    )
    assert set(overrides) == set(NODES)
    for name, params in overrides.items():
        source = (ROOT / NODE_MODULES[name]).read_text()
        names = _declared(name)
        for param in params:
            if param in (MAX_BACKLOG, BY_AGE):  # amb_tools.backlog's, for each stream reader
                assert "declare_catch_up(self)" in source, name
                continue
            declared = param in names if names else re.search(rf'["\']{param}["\']', source)
            assert declared, f"{name} does not declare parameter {param!r} set for a run"


def test_a_scenarios_samples_per_rev_reaches_every_node() -> None:
    path = scenario_file("contact_misalignment_second_bending.yaml")
    assert "samples_per_rev: 32" in path.read_text()
    overrides = run_parameters(path)
    sampling = [n for n in NODES if n != "recorder"]
    assert {n: p.get("samples_per_rev") for n, p in overrides.items()} == {
        **dict.fromkeys(sampling, 32),
        "recorder": None,
    }
    assert overrides["plant_sim"]["scenario_file"] == str(path)
    # every other node subscribes the measurements: sample 0 waits for all of them
    assert overrides["plant_sim"]["wait_for_subscribers"] == len(NODES) - 1
    without = run_parameters(path, ("wavelet_filterbank", "plant_sim"))
    assert without["plant_sim"]["wait_for_subscribers"] == 1


def test_a_scenario_without_samples_per_rev_leaves_the_params_file_in_force(tmp_path: Path):
    plain = tmp_path / "plain.yaml"
    plain.write_text("speed: {hz: 20.0}\nduration: 1.0\n")
    assert all("samples_per_rev" not in p for p in run_parameters(plain).values())


def test_a_bad_scenario_is_refused_with_its_name(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="no_such"):
        scenario_file("no_such.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("speed: {hz: 20.0}\nduration: 1.0\nsamples_per_rev: 24\n")
    with pytest.raises(ScenarioError, match="power of two"):
        run_parameters(bad)


def test_stream_readers_count_a_composed_stack_once_and_a_node_apart_on_its_own() -> None:
    coefficients, measurements = topics.COEFFICIENTS, topics.MEASUREMENT
    alone = stream_readers(NODES)
    assert (alone[measurements], alone[coefficients]) == (4, 3)  # 3 nodes + the recorder
    stack = ("wavelet_filterbank", "fault_monitor", "wavelet_controller")
    composed = stream_readers(NODES, stack)
    assert (composed[measurements], composed[coefficients]) == (2, 1)  # stack, recorder
    apart = stream_readers(NODES, ("wavelet_filterbank", "wavelet_controller"))
    assert (apart[measurements], apart[coefficients]) == (3, 2)  # + the monitor's own readers
    assert composed[topics.FAULT_EVENTS] == 1  # the recorder's: the controller's in process
    assert alone[topics.FAULT_EVENTS] == 2  # the controller's and the recorder's
    # the recorder composed too: the streams and what the stack publishes in process
    recording = stream_readers(NODES, (*stack, "recorder"))
    assert (recording[measurements], recording[coefficients]) == (1, 0)
    assert recording[topics.COMMAND] == recording[topics.FAULT_EVENTS] == 0
    assert alone[topics.COMMAND] == composed[topics.COMMAND] == 1  # the recorder's
    # the controller apart: it reads the stack's fault events over DDS, the stack its commands
    split = stream_readers(NODES, ("wavelet_filterbank", "fault_monitor", "recorder"))
    assert split[topics.FAULT_EVENTS] == 1 and split[topics.COMMAND] == 1
    # the monitor apart: the stack reads its events through one DDS reader, the recorder with it
    watched = stream_readers(NODES, ("wavelet_filterbank", "wavelet_controller", "recorder"))
    assert watched[topics.FAULT_EVENTS] == 1 and watched[topics.COMMAND] == 0
    assert apart[topics.FAULT_EVENTS] == 2  # the stack's reader and the recorder's own
    path = scenario_file("contact_misalignment_second_bending.yaml")
    for hosted, counts in (
        (stack, composed),
        (stack[::2], apart),
        ((*stack, "recorder"), recording),
    ):
        plant = run_parameters(path, hosted=hosted)["plant_sim"]
        assert plant["wait_for_subscribers"] == counts[measurements]
