"""ament_python package: builds with colcon in a ROS 2 Jazzy workspace; the bench installs it editable.

The entry points register this package's components with the bench (bench_engine.plugins)."""
from setuptools import find_packages, setup

PACKAGE = "tracker_filters"

setup(
    name=PACKAGE,
    version="0.2.0",
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
        "console_scripts": [
            "filter_node = tracker_filters.filter_node:main"],
        "tracking_bench.sections": [
            "trackers = tracker_filters.tracker_stage:read_trackers",
            "derived_measurements = tracker_filters.derived:read_derived",
            "fixed_lag_smoothers = tracker_filters.fixed_lag:read_fixed_lag",
            "filters = tracker_filters.filter_settings:read_filters",
            "filter_defaults = tracker_filters.filter_settings:read_filters"],
        "tracking_bench.node_kinds": [
            "filter = tracker_filters.filter_stage:FILTER",
            "tracker = tracker_filters.tracker_stage:TRACKER",
            "derived = tracker_filters.derived:DERIVED",
            "fixed_lag = tracker_filters.fixed_lag:FIXED_LAG"],
        "tracking_bench.estimators": [
            "kf = tracker_filters.kf:KalmanFilter",
            "ekf = tracker_filters.ekf:ExtendedKalmanFilter",
            "ekf2 = tracker_filters.ekf:SecondOrderEKF",
            "ukf = tracker_filters.ukf:UnscentedKalmanFilter",
            "cqkf = tracker_filters.cqkf:CubatureQuadratureKF",
            "sir = tracker_filters.pf:SIRParticleFilter",
            "pf = tracker_filters.pf:RegularisedParticleFilter"],
        "tracking_bench.dynamics": [
            "orbit_j2 = tracker_filters.builders:orbit_j2",
            "cw = tracker_filters.builders:cw",
            "cw_bias = tracker_filters.builders:cw_bias",
            "ss = tracker_filters.builders:ss",
            "white_jerk = tracker_filters.builders:white_jerk"],
        "tracking_bench.initialisers": [
            "first_scan = tracker_filters.builders:first_scan",
            "given = tracker_filters.builders:given",
            "truth_scaled = tracker_filters.builders:truth_scaled",
            "position_fix = tracker_filters.builders:position_fix"]
    },
)
