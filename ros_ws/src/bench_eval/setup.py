"""ament_python package: builds with colcon in a ROS 2 Jazzy workspace; the bench installs it editable.

The entry points register this package's components with the bench (bench_engine.plugins)."""

from setuptools import find_packages, setup

PACKAGE = "bench_eval"

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
            "bench_launch = bench_eval.cli.launch:command",
            "bench_score = bench_eval.cli.score:command",
            "bench_montecarlo = bench_eval.cli.montecarlo:command",
            "bench_replay = bench_eval.cli.replay:command",
            "bench_sweep = bench_eval.cli.sweep:command",
            "bench_demo = bench_eval.cli.demo:command",
            "bench_reproduce = bench_eval.cli.reproduce:command",
        ],
        "tracking_bench.sections": ["scoring = bench_eval.scoring:SCORING"],
        "tracking_bench.metrics": [
            "convergence = bench_eval.metric_families:CONVERGENCE",
            "errors = bench_eval.metric_families:ERRORS",
        ],
        "tracking_bench.offline": [
            "rts = bench_eval.offline:RTS",
            "newton = bench_eval.offline:NEWTON",
            "savgol = bench_eval.offline:SAVGOL",
        ],
        "tracking_bench.bounds": ["pcrb = bench_eval.bounds:PCRB"],
    },
)
