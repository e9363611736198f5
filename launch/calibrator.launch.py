"""Start the calibrator, and optionally the simulated rig and RViz.

    ros2 launch handeye_ros calibrator.launch.py hand_topic:=/vicon/rig/pose eye_topic:=/vio/odom
    ros2 launch handeye_ros calibrator.launch.py sim:=true auto_calibrate:=true
    ros2 launch handeye_ros calibrator.launch.py params_file:=my_calibrator.yaml rviz:=true

The topics, frames and auto_calibrate given here override the params file's; left empty, the
params file's hold (the shipped one: every parameter at its default). `ros2 launch
handeye_ros calibrator.launch.py --show-args` lists the arguments.
"""

from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

#: Node parameters a launch argument of the same name overrides when it is not empty.
OVERRIDES = {
    'hand_topic': 'the MoCap pose topic (e.g. /vicon/rig/pose, /tf:world.marker)',
    'eye_topic': 'the VO/VIO pose topic (e.g. /vio/odom)',
    'hand_frame_id': 'the marker frame H: parent of the published extrinsic',
    'eye_frame_id': 'the device frame E: child of the published extrinsic',
    'hand_world_frame_id': 'the MoCap world frame G',
    'eye_world_frame_id': "the VIO world frame W (also RViz's fixed frame)",
    'auto_calibrate': 'true: calibrate as soon as the status says READY, and as data grow',
}


def _calibrator(context, share: Path) -> list:
    """The calibrator with the params file (refused in one line if it is not a file) and
    the overrides given."""
    params_file = Path(LaunchConfiguration('params_file').perform(context)).expanduser()
    if not params_file.is_file():
        # launch_ros would only warn and start the node with every default
        raise RuntimeError(
            f'params_file {params_file} is not a file: give the path of your copy of '
            f'{share / "config" / "calibrator.yaml"}'
        )
    given = {k: LaunchConfiguration(k).perform(context) for k in OVERRIDES}
    overrides = {k: v for k, v in given.items() if v}
    if 'auto_calibrate' in overrides:
        flag = overrides['auto_calibrate'].lower()
        if flag not in ('true', 'false'):
            raise RuntimeError(
                f'auto_calibrate is true or false, not {overrides["auto_calibrate"]!r}'
            )
        overrides['auto_calibrate'] = flag == 'true'
    nodes = [
        Node(
            package='handeye_ros',
            executable='calibrator',
            name='calibrator',
            parameters=[str(params_file), overrides],
            output='screen',
            emulate_tty=True,  # the log's colours
        )
    ]
    if LaunchConfiguration('rviz').perform(context).lower() == 'true':
        nodes.append(
            Node(
                package='rviz2',
                executable='rviz2',
                arguments=[
                    '-d',
                    str(share / 'config' / 'calibrator.rviz'),
                    '-f',
                    given['eye_world_frame_id'] or 'odom',  # the node's fallback
                ],
            )
        )
    return nodes


def generate_launch_description() -> LaunchDescription:
    share = Path(get_package_share_directory('handeye_ros'))
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                'params_file',
                default_value=str(share / 'config' / 'calibrator.yaml'),
                description='the calibrator parameters (the shipped file: every default)',
            ),
            *(
                DeclareLaunchArgument(
                    name, default_value='', description=f"{text}; empty: the params file's"
                )
                for name, text in OVERRIDES.items()
            ),
            DeclareLaunchArgument(
                'sim', default_value='false', description='also start sim_publisher (a test rig)'
            ),
            DeclareLaunchArgument(
                'rviz',
                default_value='false',
                description="also start RViz on the result's paths (in eye_world_frame_id)",
            ),
            OpaqueFunction(function=_calibrator, args=[share]),
            # the simulated rig at about real time: 100 Hz MoCap + 20 Hz device for 60 s
            Node(
                package='handeye_ros',
                executable='sim_publisher',
                arguments=['--rate', '120', '--duration', '60'],
                output='screen',
                condition=IfCondition(LaunchConfiguration('sim')),
            ),
        ]
    )
