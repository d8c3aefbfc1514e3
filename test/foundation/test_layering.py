"""The imports run one way: vocabulary < cores < ROS glue < applications (issue 15).

The layers and the rules are in ``test/support/layering.py``. The test fails on any violation
(an upward, cross-core or node-to-node import, rclpy in a core, an import cycle) that is not
in ``KNOWN`` (empty today), and on a listed one that is gone; and on any import between the
top-level packages against their order (amb_common < amb_tools < the parts < amb_apps, among
the parts only the controller and the fault monitor -> amb_wavelet) or round a loop of them.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from layering import (
    Violation,
    layer_of,
    module_imports,
    package_graph,
    package_violations,
    violations,
)

ROOT = Path(__file__).resolve().parents[2]

#: Violations still in the code, and what must move to end each (none left: new ones are fixed,
#: not listed).
KNOWN: dict[Violation, str] = {}


def test_imports_keep_the_layers() -> None:
    found = set(violations(module_imports(ROOT)))
    new = sorted(found - KNOWN.keys())
    gone = sorted(KNOWN.keys() - found)
    assert not new, "imports against the layering:\n" + "\n".join(map(str, new))
    assert not gone, "fixed, take them off KNOWN:\n" + "\n".join(map(str, gone))


def test_packages_keep_their_order() -> None:
    packages = package_graph(module_imports(ROOT))
    found = package_violations(packages)
    assert not found, "imports between packages against their order:\n" + "\n".join(map(str, found))
    assert packages["amb_common"] == set()
    assert packages["amb_tools"] == {"amb_common"}
    assert not any("amb_apps" in targets for pkg, targets in packages.items() if pkg != "bench")


def _write(root: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)


@pytest.mark.parametrize(
    ("files", "expected"),
    [
        (  # rclpy in a core, even inside a function
            {"amb_wavelet/analysis.py": "def f():\n    import rclpy.node\n"},
            Violation("amb_wavelet.analysis", "rclpy", "rclpy in the core layer"),
        ),
        (  # a core importing a node
            {
                "amb_wavelet/node.py": "",
                "amb_wavelet/levels.py": "from amb_wavelet.node import stream_qos\n",
            },
            Violation("amb_wavelet.levels", "amb_wavelet.node", "upward: core imports ros"),
        ),
        (  # one node importing another part's node
            {"amb_wavelet/node.py": "", "amb_plant_sim/node.py": "from amb_wavelet import node\n"},
            Violation(
                "amb_plant_sim.node", "amb_wavelet.node", "a node imports another part's node"
            ),
        ),
        (  # a core importing another part's core (other than the wavelet core)
            {
                "amb_plant_sim/simulator.py": "",
                "amb_controller/guard.py": "import amb_plant_sim.simulator\n",
            },
            Violation(
                "amb_controller.guard",
                "amb_plant_sim.simulator",
                "a core imports another part's core",
            ),
        ),
        (  # a cycle hidden in a function, through a relative import
            {
                "amb_fault_monitor/monitor.py": "from .classifier import classify\n",
                "amb_fault_monitor/classifier.py": "def f():\n    from . import monitor\n",
            },
            Violation(
                "amb_fault_monitor.classifier",
                "amb_fault_monitor.monitor",
                "import cycle among amb_fault_monitor.classifier, amb_fault_monitor.monitor",
            ),
        ),
    ],
)
def test_a_planted_violation_is_caught(tmp_path: Path, files: dict, expected: Violation) -> None:
    _write(tmp_path, files)
    assert violations(module_imports(tmp_path)) == [expected]


@pytest.mark.parametrize(
    ("files", "expected"),
    [
        (  # the cycle amb_tools had: no module cycle, but the packages import each other
            {
                "amb_tools/conversions.py": "def f():\n    from amb_wavelet.analysis import x\n",
                "amb_wavelet/analysis.py": "",
                "amb_wavelet/node.py": "from amb_tools.conversions import stamp\n",
            },
            [
                Violation("amb_tools", "amb_wavelet", "package cycle among amb_tools, amb_wavelet"),
                Violation("amb_tools", "amb_wavelet", "package order: rank 1 imports 2"),
            ],
        ),
        (  # a part other than the controller and the fault monitor importing another part
            {
                "amb_wavelet/filters.py": "",
                "amb_plant_sim/simulator.py": "from amb_wavelet.filters import get_filters\n",
            },
            [
                Violation(
                    "amb_plant_sim", "amb_wavelet", "package order: a part imports another part"
                )
            ],
        ),
        (  # the vocabulary importing a part (both modules are errors: one layer)
            {
                "amb_plant_sim/errors.py": "",
                "amb_common/errors.py": "from amb_plant_sim.errors import ScenarioError\n",
            },
            [Violation("amb_common", "amb_plant_sim", "package order: rank 0 imports 2")],
        ),
    ],
)
def test_a_planted_package_violation_is_caught(
    tmp_path: Path, files: dict, expected: list[Violation]
) -> None:
    _write(tmp_path, files)
    graph = module_imports(tmp_path)
    assert violations(graph) == []  # the module rules alone let each of these pass
    assert package_violations(package_graph(graph)) == expected


def test_a_package_cycle_in_a_synthetic_graph_is_caught() -> None:
    packages = {
        "amb_common": set(),
        "amb_tools": {"amb_common"},
        "amb_wavelet": {"amb_common", "amb_tools"},
        "amb_controller": {"amb_wavelet", "amb_fault_monitor"},
        "amb_fault_monitor": {"amb_wavelet", "amb_controller"},
        "amb_apps": {"amb_controller"},
    }
    assert package_violations(packages) == [
        Violation(
            "amb_controller",
            "amb_fault_monitor",
            "package cycle among amb_controller, amb_fault_monitor",
        ),
        Violation(
            "amb_controller", "amb_fault_monitor", "package order: a part imports another part"
        ),
        Violation(
            "amb_fault_monitor", "amb_controller", "package order: a part imports another part"
        ),
    ]


def test_allowed_imports_pass(tmp_path: Path) -> None:
    """Each layer may use its own and those below; the other cores may use the wavelet core."""
    _write(
        tmp_path,
        {
            "amb_common/rig.py": "",
            "amb_wavelet/synthesis.py": "from amb_common.rig import load_rig\n",
            "amb_controller/transient.py": "from amb_wavelet.synthesis import x\n",
            "amb_controller/node.py": "import rclpy\nfrom amb_controller import transient\n",
            "amb_apps/run_cli.py": "import amb_controller.node\n",
            "amb_tools/node_main.py": "import rclpy\nfrom amb_common import rig\n",
            "amb_plant_sim/node.py": "from amb_tools.node_main import run_node\n",
            "bench/run.py": "from amb_apps import run_cli\n",
        },
    )
    graph = module_imports(tmp_path)
    assert violations(graph) == []
    assert package_violations(package_graph(graph)) == []
    assert [layer_of(m) for m in ("amb_common.rig", "amb_wavelet.synthesis")] == [
        "vocabulary",
        "core",
    ]
    assert [layer_of(m) for m in ("amb_controller.node", "amb_apps.run_cli")] == [
        "ros",
        "application",
    ]
    assert [layer_of(m) for m in ("amb_tools.bag_read", "amb_apps.closed_loop")] == [
        "ros",
        "application",
    ]
