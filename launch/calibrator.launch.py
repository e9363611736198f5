"""Start the calibrator, and optionally the simulated rig and RViz.

    ros2 launch handeye_ros calibrator.launch.py hand_topic:=/vicon/rig/pose eye_topic:=/vio/odom
    ros2 launch handeye_ros calibrator.launch.py sim:=true auto_calibrate:=true
    ros2 launch handeye_ros calibrator.launch.py params_file:=my_calibrator.yaml rviz:=true

The topics, frames, auto_calibrate and use_sim_time given here override the params file's; left
empty, the params file's hold (the shipped one: every parameter at its default). Every argument
is checked before any process starts: a refused one starts none. `ros2 launch handeye_ros
calibrator.launch.py --show-args` lists the arguments.
"""

from pathlib import Path

from ament_index_python.packages import (
    PackageNotFoundError,
    get_package_prefix,
    get_package_share_directory,
)
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, OpaqueFunction, RegisterEventHandler
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
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
    'use_sim_time': 'true: stamp the outputs on /clock (ros2 bag play --clock)',
}
#: The overrides that are booleans.
FLAGS = ('auto_calibrate', 'use_sim_time')
#: What a boolean argument may say (as launch's own conditions read them), and its meaning.
BOOLEANS = {'true': True, '1': True, 'false': False, '0': False}


def _flag(name: str, value: str) -> bool:
    """A boolean argument; RuntimeError (before any process starts) for another word."""
    try:
        return BOOLEANS[value.strip().lower()]
    except KeyError:
        raise RuntimeError(f'{name} is true or false, not {value!r}') from None


def _actions(context, share: Path) -> list:
    """Every process of the launch, once every argument has been checked: a refused one (in
    one line) starts none. The calibrator's end ends the launch, so that nothing it started
    is left running."""
    params_file = Path(LaunchConfiguration('params_file').perform(context)).expanduser()
    if not params_file.is_file():
        # launch_ros would only warn and start the node with every default
        raise RuntimeError(
            f'params_file {params_file} is not a file: give the path of your copy of '
            f'{share / "config" / "calibrator.yaml"}'
        )
    given = {k: LaunchConfiguration(k).perform(context) for k in OVERRIDES}
    overrides: dict = {k: v for k, v in given.items() if v}
    for name in FLAGS:
        if name in overrides:
            overrides[name] = _flag(name, overrides[name])
    sim = _flag('sim', LaunchConfiguration('sim').perform(context))
    rviz = _flag('rviz', LaunchConfiguration('rviz').perform(context))
    if rviz:
        try:
            get_package_prefix('rviz2')
        except PackageNotFoundError:
            raise RuntimeError(
                'rviz:=true needs rviz2, which is not installed (sudo apt install '
                'ros-jazzy-rviz2), or leave rviz out'
            ) from None
    namespace = LaunchConfiguration('namespace').perform(context)
    calibrator = Node(
        package='handeye_ros',
        executable='calibrator',
        name='calibrator',
        namespace=namespace,
        parameters=[str(params_file), overrides],
        output='screen',
        emulate_tty=True,  # the log's colours
    )
    actions = [
        calibrator,
        RegisterEventHandler(
            OnProcessExit(
                target_action=calibrator,
                on_exit=[EmitEvent(event=Shutdown(reason='the calibrator exited'))],
            )
        ),
    ]
    if sim:
        # the simulated rig at about real time: 100 Hz MoCap + 20 Hz device for 60 s
        actions.append(
            Node(
                package='handeye_ros',
                executable='sim_publisher',
                namespace=namespace,
                arguments=['--rate', '120', '--duration', '60'],
                output='screen',
            )
        )
    if rviz:
        actions.append(
            Node(
                package='rviz2',
                executable='rviz2',
                namespace=namespace,
                arguments=[
                    '-d',
                    str(share / 'config' / 'calibrator.rviz'),
                    '-f',
                    given['eye_world_frame_id'] or 'odom',  # the node's fallback
                ],
            )
        )
    return actions


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
                'namespace', default_value='', description='the namespace of every node'
            ),
            DeclareLaunchArgument(
                'sim', default_value='false', description='also start sim_publisher (a test rig)'
            ),
            DeclareLaunchArgument(
                'rviz',
                default_value='false',
                description="also start RViz on the result's paths (in eye_world_frame_id)",
            ),
            OpaqueFunction(function=_actions, args=[share]),
        ]
    )
