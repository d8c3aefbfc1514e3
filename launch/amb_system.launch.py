r"""The simulated rig with all four nodes and the recorder (full ROS 2 Jazzy installs).

What ``amb-run`` does where ``ros2 launch`` is not available: the same executables, the same
params file, the same per-run parameters, built by the same function
(:func:`amb_apps.system.run_parameters`: the scenario's ``samples_per_rev`` on every node, the
plant's scenario and subscriber count, the controller's choices, the recorder's bag). The
launch ends when ``plant_sim`` has finished its scenario.

    ros2 launch amb_wavelet_control amb_system.launch.py \
        scenario:=mass_loss_first_critical.yaml controller:=transient \
        model_file:=/path/model.npz start_mode:=active bag:=/tmp/run1

To drive a real rig, leave out plant_sim (``with_plant:=false``) and start your I/O bridge.
``composed:=true`` runs the filterbank, fault monitor and controller in one process
(``wavelet_stack``, :mod:`amb_apps.stack`), as ``amb-run --composed`` does.

``namespace:=/rig1`` starts every node in ``/rig1``: the topic names are relative, so the
system's topics become ``/rig1/amb/...`` and a second system in another namespace runs beside it
without crosstalk. Every node gets a namespace (``/`` by default), so that launch_ros writes the
per-run parameters under the node's fully qualified name and they win over the params file's
``/**/<node>`` sections (under ``/**`` they would lose to them).
"""

import os
import tempfile

import yaml
from launch.actions import DeclareLaunchArgument, OpaqueFunction, RegisterEventHandler, Shutdown
from launch.event_handlers import OnProcessExit
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

from amb_apps.system import (
    COMPOSED,
    NODES,
    OFF_SHARED_MEMORY,
    run_parameters,
    run_params_document,
)
from amb_common.paths import scenario_file
from amb_common.topics import namespace
from amb_tools.transport_profile import TRANSPORT_VARIABLE
from launch import LaunchDescription

PACKAGE = "amb_wavelet_control"

#: Launch arguments: (name, default, description).
ARGUMENTS = (
    ("scenario", "mass_loss_first_critical.yaml",
     "scenario YAML: a path, or a name in the package's config/scenarios"),
    ("controller", "transient",
     "wavelet_controller.controller: none | proportional | moderated | transient"),
    ("start_mode", "off", "wavelet_controller.start_mode: off | active | identify"),
    ("model_file", "", "identified model .npz for the controller ('' = none)"),
    ("model_file_out", "", "where an identification writes its model ('' = nowhere)"),
    ("params", "", "ROS params file ('' = the package's config/amb_params.yaml)"),
    ("bag", "amb_bag", "recorder output folder (must not exist)"),
    ("mode", "lockstep", "plant_sim.mode: lockstep | realtime"),
    ("with_plant", "true", "start plant_sim (false: your I/O bridge publishes the rig)"),
    ("namespace", "/", "namespace of every node (/rig1: topics /rig1/amb/...; default /)"),
    ("composed", "false",
     "true: the filterbank, fault monitor, controller and recorder in one process "
     "(wavelet_stack)"),
)  # fmt: skip


def _nodes(context) -> list:
    """The node actions, with the per-run parameters of :func:`run_parameters`."""
    value = {name: LaunchConfiguration(name).perform(context) for name, _, _ in ARGUMENTS}
    params = value["params"] or PathJoinSubstitution(
        [FindPackageShare(PACKAGE), "config", "amb_params.yaml"]
    )
    with_plant = value["with_plant"].lower() in ("true", "1", "yes")
    ns = namespace(value["namespace"])
    names = NODES if with_plant else tuple(n for n in NODES if n != "plant_sim")
    composed = value["composed"].lower() in ("true", "1", "yes")
    hosted = [n for n in COMPOSED if n in names] if composed else []
    overrides = run_parameters(
        scenario_file(value["scenario"]),
        NODES,
        controller=value["controller"],
        start_mode=value["start_mode"],
        model_file=value["model_file"],
        model_file_out=value["model_file_out"],
        mode=value["mode"],
        bag=value["bag"],
        hosted=tuple(hosted),
    )
    actions = {
        name: Node(
            package=PACKAGE,
            executable=name,
            name=name,
            namespace=ns,
            parameters=[params, overrides[name]],
            output="screen",
            # off shared memory as amb-run runs it (amb_apps.system.OFF_SHARED_MEMORY)
            additional_env={TRANSPORT_VARIABLE: "udp"} if name in OFF_SHARED_MEMORY else None,
        )
        for name in names
        if name not in hosted
    }
    if hosted:
        # One process, several nodes: no name remap (it would rename all of them); the run's
        # parameters go in a params file keyed by each node's full name, as amb-run writes it.
        fd, run_file = tempfile.mkstemp(prefix="amb_stack_", suffix=".yaml")
        with os.fdopen(fd, "w") as f:
            yaml.safe_dump(run_params_document({n: overrides[n] for n in hosted}, ns), f)
        actions["wavelet_stack"] = Node(
            package=PACKAGE,
            executable="wavelet_stack",
            namespace=ns,
            parameters=[params, run_file],
            output="screen",
        )
    if with_plant:
        plant = actions["plant_sim"]
        actions["on_plant_exit"] = RegisterEventHandler(
            OnProcessExit(target_action=plant, on_exit=[Shutdown(reason="scenario complete")])
        )
    return list(actions.values())


def generate_launch_description() -> LaunchDescription:
    """Declare the arguments (each with its description) and the five nodes."""
    arguments = [
        DeclareLaunchArgument(name, default_value=default, description=description)
        for name, default, description in ARGUMENTS
    ]
    return LaunchDescription([*arguments, OpaqueFunction(function=_nodes)])
