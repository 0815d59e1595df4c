"""ament_python package: builds with colcon in a ROS 2 Jazzy workspace; the bench installs it editable.

The entry points register this package's components with the bench (bench_engine.plugins)."""

from setuptools import find_packages, setup

PACKAGE = "orbit_sim"

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
        "tracking_bench.node_kinds": ["truth = orbit_sim.truth_source:TRUTH"],
        "tracking_bench.truth_models": [
            "cowell_j2 = orbit_sim.truth:SINGLE_ORBIT",
            "cowell_twobody = orbit_sim.truth:SINGLE_ORBIT",
            "formation_j2 = orbit_sim.truth:FORMATION",
            "formation_twobody = orbit_sim.truth:FORMATION",
            "hill_cw = orbit_sim.truth:FORMATION",
            "sgp4 = orbit_sim.truth:SGP4",
        ],
        "tracking_bench.sections": ["earth = orbit_sim.truth:EARTH", "truth = orbit_sim.truth:TRUTH"],
    },
)
