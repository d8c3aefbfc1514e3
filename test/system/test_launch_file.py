"""The launch file (not runnable here: launch is not on PyPI) names what the package installs.

Parsed, not executed: every ``executable=`` is a node console script of ``setup.py`` and every
parameter it sets is one the node declares, so a renamed node or parameter breaks this test
rather than a user's ``ros2 launch`` on the rig.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
NODE_MODULES = {
    "plant_sim": "amb_plant_sim/node.py",
    "wavelet_filterbank": "amb_wavelet/node.py",
    "fault_monitor": "amb_fault_monitor/node.py",
    "wavelet_controller": "amb_controller/node.py",
    "recorder": "amb_tools/recorder_node.py",
}


def _nodes_in_launch() -> list[tuple[str, set[str]]]:
    tree = ast.parse((ROOT / "launch" / "amb_system.launch.py").read_text())
    found = []
    for call in ast.walk(tree):
        if isinstance(call, ast.Call) and getattr(call.func, "id", None) == "Node":
            kw = {k.arg: k.value for k in call.keywords}
            names: set[str] = set()
            for item in getattr(kw.get("parameters"), "elts", []):
                if isinstance(item, ast.Dict):
                    names |= {k.value for k in item.keys}
            found.append((kw["executable"].value, names))
    return found


def test_launch_executables_are_installed_nodes() -> None:
    setup = (ROOT / "setup.py").read_text()
    nodes = _nodes_in_launch()
    assert {name for name, _ in nodes} == set(NODE_MODULES)
    for name, _ in nodes:
        assert f'"{name}": "' in setup, f"{name} is not a console script in setup.py"


def test_launch_parameters_are_declared_by_the_nodes() -> None:
    for name, params in _nodes_in_launch():
        source = (ROOT / NODE_MODULES[name]).read_text()
        for param in params:
            declared = re.search(rf'["\']{param}["\']', source)
            assert declared, f"{name} does not declare parameter {param!r} set by the launch file"
