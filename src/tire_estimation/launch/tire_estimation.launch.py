"""Launch the estimator and detector nodes (needs a full ROS 2 install with the ``launch`` and
``launch_ros`` packages; the PyPI install runs the two nodes with ``ros2 run`` or their console
scripts, README "Live").

    ros2 launch tire_estimation tire_estimation.launch.py vehicle_file:=/path/vehicle.yaml

Arguments: ``vehicle_file`` (the vehicle description; empty: the ``vehicle.*`` parameters of
the parameter files), ``params_file`` (estimator parameters, default the installed
``config/estimator.yaml``), ``detector_params_file`` (default ``config/detector.yaml``),
``use_sim_time``.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

PACKAGE = "tire_estimation"


def _node(executable: str, params_argument: str) -> Node:
    """One of the package's nodes, named as its executable, with the parameter file of the
    launch argument ``params_argument``, the vehicle file and the clock choice."""
    return Node(
        package=PACKAGE,
        executable=executable,
        name=executable,
        parameters=[
            LaunchConfiguration(params_argument),
            {
                "vehicle_file": LaunchConfiguration("vehicle_file"),
                "use_sim_time": LaunchConfiguration("use_sim_time"),
            },
        ],
        output="screen",
    )


def generate_launch_description() -> LaunchDescription:
    config = PathJoinSubstitution([FindPackageShare(PACKAGE), "config"])
    return LaunchDescription(
        [
            DeclareLaunchArgument("vehicle_file", default_value=""),
            DeclareLaunchArgument(
                "params_file", default_value=PathJoinSubstitution([config, "estimator.yaml"])
            ),
            DeclareLaunchArgument(
                "detector_params_file",
                default_value=PathJoinSubstitution([config, "detector.yaml"]),
            ),
            DeclareLaunchArgument("use_sim_time", default_value="false"),
            _node("estimator_node", "params_file"),
            _node("detector_node", "detector_params_file"),
        ]
    )
