"""The simulated rig with all four nodes and the recorder (full ROS 2 Jazzy installs).

What ``amb-run`` does where ``ros2 launch`` is not available: the same executables, the same
params file, the same overrides. The launch ends when ``plant_sim`` has finished its scenario.

    ros2 launch amb_wavelet_control amb_system.launch.py \\
        scenario:=mass_loss_first_critical.yaml controller:=transient \\
        model_file:=/path/model.npz start_mode:=active bag:=/tmp/run1

Arguments: ``scenario`` (file or name in config/scenarios), ``controller`` (none |
proportional | moderated | transient), ``start_mode`` (off | active | identify), ``model_file``,
``model_file_out``, ``params`` (default: the package's config/amb_params.yaml), ``bag``
(recorder output folder; it must not exist), ``mode`` (lockstep | realtime).
To drive a real rig, leave out plant_sim (``with_plant:=false``) and start your I/O bridge.
"""

from launch.actions import DeclareLaunchArgument, RegisterEventHandler, Shutdown
from launch.conditions import IfCondition
from launch.event_handlers import OnProcessExit
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

from launch import LaunchDescription

PACKAGE = "amb_wavelet_control"


def generate_launch_description() -> LaunchDescription:
    """Declare the arguments and the five nodes."""
    arg = LaunchConfiguration
    default_params = PathJoinSubstitution([FindPackageShare(PACKAGE), "config", "amb_params.yaml"])
    arguments = [
        DeclareLaunchArgument("scenario", default_value="mass_loss_first_critical.yaml"),
        DeclareLaunchArgument("controller", default_value="transient"),
        DeclareLaunchArgument("start_mode", default_value="off"),
        DeclareLaunchArgument("model_file", default_value=""),
        DeclareLaunchArgument("model_file_out", default_value=""),
        DeclareLaunchArgument("params", default_value=default_params),
        DeclareLaunchArgument("bag", default_value="amb_bag"),
        DeclareLaunchArgument("mode", default_value="lockstep"),
        DeclareLaunchArgument("with_plant", default_value="true"),
    ]
    params = arg("params")
    recorder = Node(
        package=PACKAGE,
        executable="recorder",
        name="recorder",
        parameters=[params, {"output": arg("bag")}],
        output="screen",
    )
    filterbank = Node(
        package=PACKAGE,
        executable="wavelet_filterbank",
        name="wavelet_filterbank",
        parameters=[params],
        output="screen",
    )
    monitor = Node(
        package=PACKAGE,
        executable="fault_monitor",
        name="fault_monitor",
        parameters=[params],
        output="screen",
    )
    controller = Node(
        package=PACKAGE,
        executable="wavelet_controller",
        name="wavelet_controller",
        parameters=[
            params,
            {
                "controller": arg("controller"),
                "start_mode": arg("start_mode"),
                "model_file": arg("model_file"),
                "model_file_out": arg("model_file_out"),
            },
        ],
        output="screen",
    )
    plant = Node(
        package=PACKAGE,
        executable="plant_sim",
        name="plant_sim",
        parameters=[
            params,
            {"scenario_file": arg("scenario"), "mode": arg("mode"), "wait_for_subscribers": 4},
        ],
        output="screen",
        condition=IfCondition(arg("with_plant")),
    )
    end_with_plant = RegisterEventHandler(
        OnProcessExit(target_action=plant, on_exit=[Shutdown(reason="scenario complete")])
    )
    return LaunchDescription(
        [*arguments, recorder, filterbank, monitor, controller, plant, end_with_plant]
    )
