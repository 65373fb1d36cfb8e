"""ament_python package definition (colcon build / ros2 run, and pip for the venv world)."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "stewart_vibration"

# Console scripts: the CLI plus one executable per node (ros2 run stewart_vibration <exe>).
CONSOLE_SCRIPTS = [
    "stewart-vibration = stewart_vibration.cli.main:main",
    "mcap_recorder = stewart_vibration.nodes.mcap_recorder_node:main",
    "mcap_replay = stewart_vibration.nodes.mcap_replay_node:main",
    "kinematics_node = stewart_vibration.nodes.kinematics_node:main",
    "vibration_planner_node = stewart_vibration.nodes.vibration_planner_node:main",
    "leg_force_estimator_node = stewart_vibration.nodes.leg_force_estimator_node:main",
    "hardware_emulator_node = stewart_vibration.nodes.hardware_emulator_node:main",
    "planning_ui = stewart_vibration.nodes.planning_ui_node:main",
    "foxglove_bridge = stewart_vibration.nodes.foxglove_bridge_node:main",
]

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*"]),
    package_data={"stewart_vibration.ui": ["static/*"]},  # the planning UI's page
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        # config: robot, scenarios, node parameters (yaml), the DDS profile (xml), the Foxglove layout (json)
        (f"share/{PACKAGE}/config", glob("config/*.yaml") + glob("config/*.xml") + glob("config/*.json")),
        (f"share/{PACKAGE}/launch", glob("launch/*.launch.py")),
    ],
    install_requires=["setuptools"],
    zip_safe=False,
    maintainer="stewart_vibration developers",
    maintainer_email="dev@stewart-vibration.invalid",
    description="Vibration planning and emulation for a 6-UPS tibia fracture reduction robot",
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={"console_scripts": CONSOLE_SCRIPTS},
)
