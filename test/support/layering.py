"""The package's layers and a checker of the imports between them (issue 15).

Four layers, each importing only its own and those below:

1. ``vocabulary``: the package ``amb_common`` (names, topics, paths, the rig loader and its
   error, fault kinds) and each part's ``errors`` (names every part shares);
2. ``core``: the ROS-free numerics of each part (arrays in, arrays out). A core imports the
   vocabulary, its own part's core and the wavelet core (``amb_wavelet``: the filterbank is the
   language the controller and the fault monitor are written in), never another part's core;
3. ``ros``: each part's ``node.py`` (and its other message modules) and the shared ROS glue,
   the package ``amb_tools`` (message conversion, CDR, node main, recorder, bags). A node never
   imports another part's node;
4. ``application``: the package ``amb_apps`` (command lines across the parts, the in-process
   loop, experiments, reports), a part's own ``*_cli`` and plots, and the benchmarks.

``rclpy`` belongs to the last two. Every import counts, those inside functions too (they hide
cycles, not remove them), and no two modules may import each other, directly or round a loop.

The packages keep the same order as a whole (:func:`package_violations`): ``amb_common`` <
``amb_tools`` < the parts < ``amb_apps``, where among the parts only the controller and the
fault monitor import another part, the wavelet one; ``bench/`` may import anything, and no
package imports ``amb_apps``. A package imports another when any of its modules imports any
module of the other, and the graph of the packages has no cycle.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

PACKAGES = (
    "amb_common",
    "amb_tools",
    "amb_wavelet",
    "amb_plant_sim",
    "amb_controller",
    "amb_fault_monitor",
    "amb_apps",
)
LAYERS = ("vocabulary", "core", "ros", "application")
#: The part whose core the other cores may use.
SHARED_CORE = "amb_wavelet"

#: Whole packages of one layer.
PACKAGE_LAYER = {"amb_common": "vocabulary", "amb_tools": "ros", "amb_apps": "application"}
#: Modules of a part outside its core (besides ``node``, ``errors`` and ``*_cli``).
ROS = {
    "amb_controller.node_params",  # the node's parameters <-> ControllerConfig
    "amb_fault_monitor.blackbox",  # the node's black-box bags
    "amb_fault_monitor.coefficient_messages",  # the node's check and conversion of messages
    "amb_fault_monitor.node_params",  # the node's parameters <-> MonitorConfig
    "amb_plant_sim.node_params",  # the node's parameters and the run they configure
    "amb_wavelet.messages",  # the coefficient messages (filterbank records <-> amb_msgs)
}
APPLICATION = {
    "amb_plant_sim.plots",  # amb-modal's figures
}

#: The parts: each imports amb_common and amb_tools, and only those of PART_IMPORTS.
PARTS = ("amb_wavelet", "amb_plant_sim", "amb_controller", "amb_fault_monitor")
PART_IMPORTS = {"amb_controller": {SHARED_CORE}, "amb_fault_monitor": {SHARED_CORE}}
#: Rank of each package: a package imports only those of a lower rank (the parts: PART_IMPORTS).
PACKAGE_RANK = {"amb_common": 0, "amb_tools": 1, **dict.fromkeys(PARTS, 2), "amb_apps": 3}
#: Importers outside the packages that may import any package (amb_apps included).
TOP = {"bench"}


def layer_of(module: str) -> str:
    """The layer of a dotted module name (``bench.*`` and ``*_cli`` are applications)."""
    package = module.split(".")[0]
    name = module.rsplit(".", 1)[-1]
    if package in PACKAGE_LAYER:
        return PACKAGE_LAYER[package]
    if name == "errors":
        return "vocabulary"
    if module in ROS or name == "node":
        return "ros"
    if module in APPLICATION or name.endswith("_cli") or package in TOP:
        return "application"
    return "core"


@dataclass(frozen=True, order=True)
class Violation:
    """One import against the layering: ``importer`` imports ``imported`` (``rule`` says how)."""

    importer: str
    imported: str
    rule: str

    def __str__(self) -> str:
        return f"{self.importer} -> {self.imported}: {self.rule}"


def module_imports(root: Path, packages: Iterable[str] = PACKAGES) -> dict[str, set[str]]:
    """
    Every project module below ``root`` (and ``bench/``) and the project modules it imports.

    Imports of a package's ``__init__`` count as imports of the package; relative imports are
    resolved; names imported from a module (``from a.b import c``) count as ``a.b`` unless
    ``a.b.c`` is a module itself.
    """
    packages = tuple(packages)
    files = {}
    for pkg in (*packages, "bench"):
        for path in sorted((root / pkg).glob("*.py")):
            mod = f"{pkg}.{path.stem}" if path.stem != "__init__" else pkg
            files[mod] = path
    graph: dict[str, set[str]] = {}
    for mod, path in files.items():
        out: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parent = mod.split(".")[: -node.level] if path.stem != "__init__" else [mod]
                    base = ".".join([*parent, base] if base else parent)
                targets = [
                    f"{base}.{a.name}" if f"{base}.{a.name}" in files else base for a in node.names
                ]
            for t in targets:
                if t.split(".")[0] == "rclpy":
                    out.add("rclpy")
                elif t.split(".")[0] in packages:
                    while t not in files and "." in t:
                        t = t.rsplit(".", 1)[0]
                    if t in files and t != mod:
                        out.add(t)
        graph[mod] = out
    return graph


def violations(graph: dict[str, set[str]]) -> list[Violation]:
    """The imports of ``graph`` (from :func:`module_imports`) that break the layering."""
    rank = {name: k for k, name in enumerate(LAYERS)}
    found: set[Violation] = set()
    for mod, targets in graph.items():
        layer = layer_of(mod)
        part = mod.split(".")[0]
        for t in targets:
            if t == "rclpy":
                if rank[layer] < rank["ros"]:
                    found.add(Violation(mod, t, f"rclpy in the {layer} layer"))
                continue
            t_layer, t_part = layer_of(t), t.split(".")[0]
            if rank[t_layer] > rank[layer]:
                found.add(Violation(mod, t, f"upward: {layer} imports {t_layer}"))
            elif layer == t_layer == "core" and t_part not in (part, SHARED_CORE):
                found.add(Violation(mod, t, "a core imports another part's core"))
            elif layer == t_layer == "ros" and t.endswith(".node") and t_part != part:
                found.add(Violation(mod, t, "a node imports another part's node"))
    for group in cycles(graph):
        found.add(Violation(group[0], group[1], "import cycle among " + ", ".join(group)))
    return sorted(found)


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected groups of more than one module (Tarjan), each as a sorted list."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    groups: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in graph:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                groups.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(groups)


def package_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """The top-level packages of ``graph`` (from :func:`module_imports`) and those each imports.

    ``a`` imports ``b`` when any module of ``a`` imports any module of ``b`` (inner imports
    included, as in ``graph``); ``rclpy`` is left out (the module rules place it).
    """
    packages: dict[str, set[str]] = {}
    for mod, targets in graph.items():
        a = mod.split(".")[0]
        out = packages.setdefault(a, set())
        out.update(b for b in (t.split(".")[0] for t in targets) if b not in (a, "rclpy"))
    return packages


def package_violations(packages: dict[str, set[str]]) -> list[Violation]:
    """The imports between packages (from :func:`package_graph`) against their order.

    Each import must go to a package of a lower :data:`PACKAGE_RANK` (among the parts only
    those of :data:`PART_IMPORTS`; :data:`TOP` may import anything), and no packages may import
    each other, directly or round a loop.
    """
    found: set[Violation] = set()
    for a, targets in packages.items():
        if a in TOP:
            continue
        for b in targets:
            if a in PARTS and b in PARTS:
                if b not in PART_IMPORTS.get(a, ()):
                    found.add(Violation(a, b, "package order: a part imports another part"))
            elif b not in PACKAGE_RANK or a not in PACKAGE_RANK:
                found.add(Violation(a, b, "package order: a package outside PACKAGE_RANK"))
            elif PACKAGE_RANK[b] >= PACKAGE_RANK[a]:
                found.add(
                    Violation(
                        a, b, f"package order: rank {PACKAGE_RANK[a]} imports {PACKAGE_RANK[b]}"
                    )
                )
    for group in cycles(packages):
        found.add(Violation(group[0], group[1], "package cycle among " + ", ".join(group)))
    return sorted(found)
