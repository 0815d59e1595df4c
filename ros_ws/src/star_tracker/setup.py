"""ament_python package: builds with colcon in a ROS 2 Jazzy workspace; the bench installs it editable.

The entry points register this package's components with the bench (bench_engine.plugins); the core modules
of this first version register none yet."""
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
    entry_points={},
)
