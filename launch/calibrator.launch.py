"""Start the calibrator with the shipped params file, and optionally the simulated rig.

    ros2 launch handeye_ros calibrator.launch.py
    ros2 launch handeye_ros calibrator.launch.py sim:=true params_file:=/path/to/mine.yaml
    ros2 launch handeye_ros calibrator.launch.py rviz:=true   (the paths of each result)

Topics are the params file's (hand_topic, eye_topic); remap them with the node's parameters.
"""

from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description() -> LaunchDescription:
    share = Path(get_package_share_directory('handeye_ros'))
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                'params_file',
                default_value=str(share / 'config' / 'calibrator.yaml'),
                description='the calibrator parameters (every option with its default)',
            ),
            DeclareLaunchArgument(
                'sim', default_value='false', description='also start sim_publisher (a test rig)'
            ),
            DeclareLaunchArgument(
                'rviz', default_value='false', description='also start RViz on the result paths'
            ),
            Node(
                package='handeye_ros',
                executable='calibrator',
                name='calibrator',
                parameters=[LaunchConfiguration('params_file')],
                output='screen',
                emulate_tty=True,  # the status line redraws in place
            ),
            Node(
                package='handeye_ros',
                executable='sim_publisher',
                arguments=['--rate', '120', '--duration', '60'],
                output='screen',
                condition=IfCondition(LaunchConfiguration('sim')),
            ),
            Node(
                package='rviz2',
                executable='rviz2',
                arguments=['-d', str(share / 'config' / 'calibrator.rviz')],
                condition=IfCondition(LaunchConfiguration('rviz')),
            ),
        ]
    )
