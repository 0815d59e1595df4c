"""ament_python package: builds with colcon in a ROS 2 Jazzy workspace; the bench installs it editable.

The entry points register this package's components with the bench (bench_engine.plugins)."""

from setuptools import find_packages, setup

PACKAGE = "bench_engine"

setup(
    name=PACKAGE,
    version="0.2.0",
    packages=find_packages(exclude=["test"]),
    package_data={PACKAGE: ["dds/*.xml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + PACKAGE]),
        ("share/" + PACKAGE, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=False,
    maintainer="Tracking bench team",
    maintainer_email="bench@example.org",
    description=open("package.xml").read().split("<description>")[1].split("</description>")[0],
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "stage_node = bench_engine.stage_node:main",
            "source_node = bench_engine.source_node:main",
            "recorder_node = bench_engine.recorder_node:main",
            "player_node = bench_engine.player_node:main",
            "bench_recover_bag = bench_engine.cli.recover_bag:command",
        ],
        "tracking_bench.node_kinds": ["recorder = bench_engine.kinds:RECORDER", "player = bench_engine.kinds:PLAYER"],
        "tracking_bench.codecs": [
            "bench_msgs.msg.TruthState = bench_engine.stage:TRUTH_CODEC",
            "bench_msgs.msg.StateEstimate = bench_engine.stage:ESTIMATE_CODEC",
        ],
    },
)
