"""
The node set of one run and the parameters a run sets on each node.

``amb-run`` (:mod:`amb_apps.run_cli`) and the launch file (``launch/amb_system.launch.py``)
start the same five nodes with the same params file and build their per-run overrides here, so
that the two ways of starting the system cannot drift apart (a test of
:func:`run_parameters` covers both). What a run sets on top of the params file:

- ``samples_per_rev`` on every node but the recorder, when the scenario names it (the fault
  scenarios run at 32 samples per revolution, the params file says 64): the plant's own rule
  (:func:`amb_plant_sim.scenario.resolve_samples_per_rev`), given to all nodes so that they
  agree;
- the plant's ``scenario_file``, ``mode`` and ``wait_for_subscribers`` (every other node
  started subscribes to ``/amb/measurement``: sample 0 waits for all of them);
- the controller's ``controller``, ``start_mode``, ``model_file``, ``model_file_out`` when
  given;
- the recorder's ``output`` folder and the streams it subscribes at start
  (``topic_types``: nothing is lost before discovery).
"""

from __future__ import annotations

from pathlib import Path

from amb_common import topics
from amb_plant_sim.scenario import load_scenario

__all__ = ["NODES", "NODE_MODULES", "param_text", "ros_arguments", "run_parameters"]

#: The nodes of a run, in start order (the plant last: it waits for the others).
NODES = ("recorder", "wavelet_filterbank", "fault_monitor", "wavelet_controller", "plant_sim")
#: The module of each node's executable (``python -m`` where it is not installed).
NODE_MODULES = {
    "recorder": "amb_tools.recorder_node",
    "wavelet_filterbank": "amb_wavelet.node",
    "fault_monitor": "amb_fault_monitor.node",
    "wavelet_controller": "amb_controller.node",
    "plant_sim": "amb_plant_sim.node",
}


def run_parameters(
    scenario: Path,
    nodes: tuple[str, ...] = NODES,
    *,
    controller: str = "",
    start_mode: str = "",
    model_file: str = "",
    model_file_out: str = "",
    mode: str = "",
    bag: str = "",
) -> dict[str, dict[str, object]]:
    """
    The parameters a run sets on each node, on top of the params file (module docstring).

    Parameters
    ----------
    scenario : pathlib.Path
        The scenario file (:func:`amb_common.paths.scenario_file`).
    nodes : tuple of str
        The nodes started (a subset of :data:`NODES`; ``plant_sim`` among them).
    controller, start_mode, model_file, model_file_out : str
        ``wavelet_controller`` parameters; empty: the params file's.
    mode : str
        ``plant_sim`` mode (``lockstep`` | ``realtime``); empty: the params file's.
    bag : str
        The recorder's output folder; empty: the params file's.

    Returns
    -------
    dict
        Node name -> {parameter: value} for every node of ``nodes``.

    Raises
    ------
    amb_plant_sim.errors.ScenarioError
        If the scenario file is not a valid scenario.
    """
    spr = load_scenario(scenario).samples_per_rev
    out: dict[str, dict[str, object]] = {n: {} for n in nodes}
    for name, params in out.items():
        if spr and name != "recorder":  # the recorder does not sample
            params["samples_per_rev"] = int(spr)
    plant = out["plant_sim"]
    plant["scenario_file"] = str(scenario)
    plant["wait_for_subscribers"] = len(nodes) - 1
    if mode:
        plant["mode"] = mode
    if "wavelet_controller" in out:
        given = {
            "controller": controller,
            "start_mode": start_mode,
            "model_file": model_file,
            "model_file_out": model_file_out,
        }
        out["wavelet_controller"].update({k: v for k, v in given.items() if v})
    if "recorder" in out:
        if bag:
            out["recorder"]["output"] = bag
        out["recorder"]["topic_types"] = [f"{t}:{m}" for t, m in topics.STREAM_TYPES.items()]
    return out


def ros_arguments(node: str, params: dict[str, object]) -> list[str]:
    """
    ``-p node:name:=value`` arguments for ``params`` (node-scoped: see below).

    rcl ranks a node's section of a params file above an unscoped ``-p``, so ``-p mode:=...``
    would lose to ``plant_sim: mode: lockstep``; a node-scoped ``-p`` wins.
    """
    args: list[str] = []
    for name, value in params.items():
        args += ["-p", f"{node}:{name}:={param_text(value)}"]
    return args


def param_text(value: object) -> str:
    """A value as the text of a ``-p name:=value`` argument (YAML: bools, lists, quoted strings)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return (
            "[" + ",".join(f'"{v}"' if isinstance(v, str) else param_text(v) for v in value) + "]"
        )
    return str(value)
