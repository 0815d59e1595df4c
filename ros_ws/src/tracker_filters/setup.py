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
        "console_scripts": ["filter_node = tracker_filters.filter_node:main"],
        "tracking_bench.sections": [
            "trackers = tracker_filters.tracker_stage:TRACKERS",
            "derived_measurements = tracker_filters.derived:DERIVED_MEASUREMENTS",
            "fixed_lag_smoothers = tracker_filters.fixed_lag:FIXED_LAG_SMOOTHERS",
            "filters = tracker_filters.filter_settings:FILTERS",
            "filter_defaults = tracker_filters.filter_settings:FILTER_DEFAULTS",
        ],
        "tracking_bench.node_kinds": [
            "filter = tracker_filters.filter_stage:FILTER",
            "tracker = tracker_filters.tracker_stage:TRACKER",
            "derived = tracker_filters.derived:DERIVED",
            "fixed_lag = tracker_filters.fixed_lag:FIXED_LAG",
        ],
        "tracking_bench.estimators": [
            "kf = tracker_filters.kf:KalmanFilter",
            "ekf = tracker_filters.ekf:ExtendedKalmanFilter",
            "ekf2 = tracker_filters.ekf:SecondOrderEKF",
            "ukf = tracker_filters.ukf:UnscentedKalmanFilter",
            "cqkf = tracker_filters.cqkf:CubatureQuadratureKF",
            "sir = tracker_filters.pf:SIRParticleFilter",
            "pf = tracker_filters.pf:RegularisedParticleFilter",
        ],
        "tracking_bench.dynamics": [
            "orbit_j2 = tracker_filters.filter_settings:ORBIT_J2",
            "cw = tracker_filters.filter_settings:CW",
            "cw_bias = tracker_filters.filter_settings:CW_BIAS",
            "ss = tracker_filters.filter_settings:SS",
            "white_jerk = tracker_filters.filter_settings:WHITE_JERK",
        ],
        "tracking_bench.initialisers": [
            "first_scan = tracker_filters.filter_settings:FIRST_SCAN",
            "given = tracker_filters.filter_settings:GIVEN",
            "truth_scaled = tracker_filters.filter_settings:TRUTH_SCALED",
            "position_fix = tracker_filters.filter_settings:POSITION_FIX",
        ],
    },
)
