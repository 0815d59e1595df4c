"""ament_python package: builds with colcon in a ROS 2 Jazzy workspace; the bench installs it editable.

The entry points register this package's components with the bench (bench_engine.plugins): the attitude
truth, the star camera (sensor) and star tracker (estimator) node kinds with their sections, and the codec of
bench_msgs/StarCentroids."""

from setuptools import find_packages, setup

PACKAGE = "star_tracker"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
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
        "tracking_bench.truth_models": ["lvlh_camera = star_tracker.truth_settings:CAMERA_TRUTH"],
        "tracking_bench.node_kinds": [
            "star_camera = star_tracker.camera_stage:STAR_CAMERA",
            "star_tracker = star_tracker.tracker_stage:STAR_TRACKER",
        ],
        "tracking_bench.sections": [
            "star_cameras = star_tracker.camera_stage:CAMERAS",
            "star_trackers = star_tracker.tracker_stage:TRACKERS_SECTION",
            "star_tracker_defaults = star_tracker.tracker_stage:TRACKER_DEFAULTS",
        ],
        "tracking_bench.codecs": ["bench_msgs.msg.StarCentroids = star_tracker.messages:STAR_CENTROIDS"],
    },
)
