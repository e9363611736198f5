"""ament_python build of handeye_ros (colcon build, or pip for the core alone).

Versions are pinned in one place, requirements.txt; here only the names, with the lower bounds
of the ROS 2 Jazzy platform (Ubuntu 24.04's packages, requirements-jazzy.txt), which the suite
also runs on.
"""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'handeye_ros'
#: ``ros2 run handeye_ros NAME``: the function each command runs.
COMMANDS = {
    'calibrator': 'handeye_ros.ros.calibrator:main',
    'offline_calibrate': 'handeye_ros.app.offline:main',
    'sim_publisher': 'handeye_ros.ros.sim_publisher:main',
    'demo': 'handeye_ros.app.demo:main',
    'evaluate': 'handeye_ros.app.evaluate:main',
    'publish_calibration': 'handeye_ros.ros.publish_calibration:main',
}

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(include=[PACKAGE, f'{PACKAGE}.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', [f'resource/{PACKAGE}']),
        (f'share/{PACKAGE}', ['package.xml']),
        (f'share/{PACKAGE}/config', glob('config/*.yaml') + glob('config/*.rviz')),
        (f'share/{PACKAGE}/launch', glob('launch/*.launch.py')),
        (f'lib/{PACKAGE}', [f'ros2_run/{name}' for name in COMMANDS]),
    ],
    python_requires='>=3.11',
    install_requires=[
        'numpy>=1.26.4',
        'scipy>=1.11.4',
        'pyyaml>=6.0.1',
        'rosbags>=0.11.9',
        'tqdm>=4.66.2',
    ],
    extras_require={
        # the ROS 2 side (node, message conversion); from PyPI wheels or a Jazzy install
        'ros': ['ros-jazzy-rclpy[fastrtps]', 'ros-jazzy-common-interfaces', 'ros-jazzy-std-srvs'],
        # the report's plots
        'report': ['matplotlib>=3.6.3'],
        # many recordings (handeye_ros.evaluate)
        'evaluate': ['dask', 'distributed', 'matplotlib>=3.6.3'],
        # evo (GPLv3) only checks our exports in the tests; the package never imports it
        'test': ['pytest', 'hypothesis', 'ruff', 'evo'],
        # comparison baselines, for bench/ only
        'bench': ['opencv-python-headless', 'matplotlib'],
    },
    zip_safe=True,
    maintainer='handeye_ros maintainers',
    maintainer_email='maintainers@handeye-ros.invalid',
    description='Time offset and hand-eye extrinsic between MoCap and VO/VIO trajectories',
    license='Apache-2.0',
    # the commands on a pip install's PATH, and in a colcon install's bin/, carry the package's
    # name (app/commands.py); ``ros2 run handeye_ros NAME`` starts ros2_run/NAME, installed
    # into lib/handeye_ros/ above, where ros2 run looks
    entry_points={
        'console_scripts': [
            f'handeye-ros-{name.replace("_", "-")} = {target}' for name, target in COMMANDS.items()
        ],
    },
)
