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
- in ``realtime``, when the scenario names ``samples_per_rev``, ``max_backlog`` on the nodes
  that read the measurements: :data:`REALTIME_BACKLOG_REVS` revolutions, so that a node thrown
  behind by an overload drops the oldest samples and catches up (:mod:`amb_tools.backlog`;
  lock-step keeps every sample);
- the controller's ``controller``, ``start_mode``, ``model_file``, ``model_file_out`` when
  given;
- the recorder's ``output`` folder and the streams it subscribes at start
  (``topic_types``, relative names resolved in the recorder's namespace: nothing is lost before
  discovery).

Namespace: both start every node in one namespace (``/`` by default; ``amb-run --namespace``,
the launch file's ``namespace``). The topic names are relative (:mod:`amb_common.topics`), so
that the namespace moves the whole system. A params file's node sections must then match a node
in any namespace (``/**/plant_sim:``, as ``config/amb_params.yaml`` writes them; a bare
``plant_sim:`` matches only ``/plant_sim``), and a run's own parameters are given as a second
params file with each node's section under its fully qualified name
(:func:`run_params_document`): rclpy takes the later section, so they win over the params
file's, in any namespace. (A node-scoped ``-p plant_sim:mode:=...`` cannot name a node in a
namespace, and an unscoped ``-p`` loses to the params file's node sections.)
"""

from __future__ import annotations

from pathlib import Path

from amb_common import topics
from amb_plant_sim.scenario import load_scenario

__all__ = [
    "COMPOSED",
    "NODES",
    "NODE_MODULES",
    "PUBLISHERS",
    "REALTIME_BACKLOG_REVS",
    "STACK",
    "node_name",
    "param_text",
    "run_parameters",
    "run_params_document",
    "stream_readers",
]

#: The nodes of a run, in start order (the plant last: it waits for the others).
NODES = ("recorder", "wavelet_filterbank", "fault_monitor", "wavelet_controller", "plant_sim")
#: The module of each node's executable (``python -m`` where it is not installed).
NODE_MODULES = {
    "recorder": "amb_tools.recorder_node",
    "wavelet_filterbank": "amb_wavelet.node",
    "fault_monitor": "amb_fault_monitor.node",
    "wavelet_controller": "amb_controller.node",
    "plant_sim": "amb_plant_sim.node",
    "wavelet_stack": "amb_apps.stack",  # the other nodes but the plant composed in one process
}
#: The nodes ``wavelet_stack`` composes (``amb-run --composed``, the launch file's composed:=true),
#: in creation order: the recorder last, once the streams it takes in process are on the bus.
COMPOSED = ("wavelet_filterbank", "fault_monitor", "wavelet_controller", "recorder")
#: The composed nodes that read the measurements with a catch-up bound (not the recorder).
SAMPLING = tuple(n for n in COMPOSED if n != "recorder")
#: The executable composing them.
STACK = "wavelet_stack"
#: The processes run off shared memory (``AMB_TRANSPORT=udp``; ``amb-run --udp/--shm``, the
#: launch file). The recorder, niced and off the control loop, is the reader most often
#: descheduled: on shared memory its listener, descheduled while it holds its port's mutex,
#: holds the plant's and the filterbank's writes (``amb_tools.transport_profile``; measured with
#: ``test/reliability/probe_stopped_reader.py``: ``docs/history.md``, "Off shared memory").
OFF_SHARED_MEMORY = ("recorder",)
#: The node publishing each stream (composed or not: each node reports under its own name).
PUBLISHERS = {
    topics.MEASUREMENT: "plant_sim",
    topics.COEFFICIENTS: "wavelet_filterbank",
    topics.COMMAND: "wavelet_controller",
    topics.STATUS: "wavelet_controller",
    topics.FAULT_EVENTS: "fault_monitor",
}
#: Revolutions of measurements a realtime reader keeps when it is further behind (it drops the
#: older ones). With the thesis's delay i = 2 a command made from a period more than two
#: periods old is late, but each drop is a gap: the controller resets its filters and the
#: monitor calibrates again. A bound of a few periods turned the jitter of a node set near its
#: capacity into a reset storm (docs/history.md, "Realtime catch-up bound"); 8 revolutions
#: leave that jitter alone and still bound a real stall.
REALTIME_BACKLOG_REVS = 8


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
    hosted: tuple[str, ...] = (),
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
    hosted : tuple of str
        The nodes composed in ``wavelet_stack`` (:data:`COMPOSED`): they read the
        measurements through one DDS reader, which the plant counts once.

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
    # every other node reads the measurements; the composed ones through one reader
    plant["wait_for_subscribers"] = stream_readers(nodes, hosted)[topics.MEASUREMENT]
    if mode:
        plant["mode"] = mode
    if mode == "realtime" and spr:
        for name in SAMPLING:
            if name in out:
                out[name]["max_backlog"] = REALTIME_BACKLOG_REVS * int(spr)
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


def stream_readers(names, hosted: tuple[str, ...] = ()) -> dict[str, int]:
    """
    DDS readers each stream has once the nodes ``names`` are up (the plant waits for its count).

    Parameters
    ----------
    names : iterable of str
        The nodes started (of :data:`NODES`).
    hosted : tuple of str
        Those composed in ``wavelet_stack`` (the filterbank among them): they share one DDS
        reader of the measurements and read what the others composed with them publish in
        process (:mod:`amb_tools.local_bus`); a node started apart reads over DDS.

    Returns
    -------
    dict
        Topic -> readers, for the streams whose publisher is started; the recorder subscribes
        every stream at start (``topic_types``), so it counts on each (composed, not on those
        it takes in process).
    """
    has = set(names)
    recorder = int("recorder" in has)
    consumers = {
        topics.MEASUREMENT: {"wavelet_filterbank", "fault_monitor", "wavelet_controller"},
        topics.COEFFICIENTS: {"fault_monitor", "wavelet_controller"},
        topics.COMMAND: set(),
        topics.STATUS: set(),
        topics.FAULT_EVENTS: {"wavelet_controller"},
    }
    stack_published = {t for t, node in PUBLISHERS.items() if node in hosted}
    # read from outside by a composed node: through the stack's one DDS reader, which a
    # composed recorder joins in process
    shared = {t for t, nodes in consumers.items() if nodes & set(hosted)} - stack_published
    in_process = shared | stack_published if "recorder" in hosted else set()
    if hosted:
        for topic in shared:
            consumers[topic] = (consumers[topic] - set(hosted)) | {STACK}
        for topic in stack_published:
            consumers[topic] -= set(hosted)
        has.add(STACK)
    return {
        topic: len(nodes & has) + (recorder if topic not in in_process else 0)
        for topic, nodes in consumers.items()
        if PUBLISHERS[topic] in has
    }


def node_name(node: str, namespace: str = topics.ROOT_NAMESPACE) -> str:
    """The fully qualified name of ``node`` started in ``namespace`` (``/rig1/plant_sim``)."""
    return topics.absolute(node, namespace)


def run_params_document(
    params: dict[str, dict[str, object]], namespace: str = topics.ROOT_NAMESPACE
) -> dict[str, dict]:
    """
    A params-file document of a run's parameters: each node's under its fully qualified name.

    Given to every node after the params file (``--params-file FILE --params-file RUN``), a
    node's section here comes after the file's ``/**`` and ``/**/node`` sections and so wins
    over them (module notes); nodes with nothing to set have no section.

    Parameters
    ----------
    params : dict
        Node name -> {parameter: value} (:func:`run_parameters`, user overrides).
    namespace : str
        The namespace every node is started in.
    """
    return {
        node_name(node, namespace): {"ros__parameters": dict(values)}
        for node, values in params.items()
        if values
    }


def param_text(value: object) -> str:
    """A value as the text of a ``-p name:=value`` argument (YAML: bools, lists, quoted strings)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return (
            "[" + ",".join(f'"{v}"' if isinstance(v, str) else param_text(v) for v in value) + "]"
        )
    return str(value)
