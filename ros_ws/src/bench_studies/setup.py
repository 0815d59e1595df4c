"""ament_python package: builds with colcon in a ROS 2 Jazzy workspace; the bench installs it editable.

The entry points register this package's components with the bench (bench_engine.plugins)."""

from setuptools import find_packages, setup

PACKAGE = "bench_studies"

setup(
    name=PACKAGE,
    version="0.2.0",
    packages=find_packages(exclude=["test"]),
    package_data={PACKAGE: ["*/*.yaml"]},
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
        "tracking_bench.scenarios": [
            "leo_radar = bench_studies.leo_radar:SCENARIO",
            "formation_pf = bench_studies.formation_pf:SCENARIO",
            "formation_cqkf = bench_studies.formation_cqkf:SCENARIO",
            "grace_velocity = bench_studies.grace_velocity:SCENARIO",
            "star_tracker = bench_studies.star_tracker:SCENARIO",
        ],
        "tracking_bench.studies": [
            "leo_radar = bench_studies.leo_radar.study:STUDY",
            "formation_pf = bench_studies.formation_pf.study:STUDY",
            "formation_cqkf = bench_studies.formation_cqkf.study:STUDY",
            "grace_velocity = bench_studies.grace_velocity.study:STUDY",
            "star_tracker = bench_studies.star_tracker.study:STUDY",
        ],
        "tracking_bench.metrics": [
            "radar_convergence = bench_studies.leo_radar.metrics:RADAR_CONVERGENCE",
            "range_rate = bench_studies.grace_velocity.metrics:RANGE_RATE",
            "star_attitude = bench_studies.star_tracker.metrics:STAR_ATTITUDE",
        ],
        "tracking_bench.bounds": [
            "wahba = bench_studies.star_tracker.bounds:WAHBA",
            "wahba_tracked = bench_studies.star_tracker.bounds:WAHBA_TRACKED",
            "orbit_crb = bench_studies.grace_velocity.bounds:ORBIT_CRB",
        ],
        "tracking_bench.truth_models": [
            "pair_j2 = bench_studies.grace_velocity.pair_settings:PAIR",
            "pair_hifi = bench_studies.grace_velocity.pair_settings:PAIR",
        ],
        "tracking_bench.offline": ["pair_orbit_fit = bench_studies.grace_velocity.pair_fit:PAIR_ORBIT_FIT"],
    },
)
