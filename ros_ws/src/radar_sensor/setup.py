"""ament_python package: builds with colcon in a ROS 2 Jazzy workspace; the bench installs it editable.

The entry points register this package's components with the bench (bench_engine.plugins)."""

from setuptools import find_packages, setup

PACKAGE = "radar_sensor"

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
        "console_scripts": ["sensor_node = radar_sensor.sensor_node:main"],
        "tracking_bench.node_kinds": [
            "sensor = radar_sensor.sensor_stage:SENSOR",
            "cluttered_sensor = radar_sensor.clutter:CLUTTERED_SENSOR",
        ],
        "tracking_bench.sensors": [
            "ground_radar = radar_sensor.sensor:GROUND_RADAR",
            "isl_radio = radar_sensor.sensor:ISL_RADIO",
            "relative_position = radar_sensor.sensor:RELATIVE_POSITION",
            "gnss = radar_sensor.gnss:GNSS",
            "kbr = radar_sensor.gnss:KBR",
        ],
        "tracking_bench.codecs": [
            "bench_msgs.msg.RangeAzEl = radar_sensor.messages:RANGE_AZ_EL",
            "bench_msgs.msg.VectorMeasurement = radar_sensor.messages:VECTOR_MEASUREMENT",
            "bench_msgs.msg.DetectionSet = radar_sensor.messages:DETECTION_SET",
        ],
        "tracking_bench.sections": [
            "cluttered_sensors = radar_sensor.clutter:CLUTTERED_SENSORS",
            "sensors = radar_sensor.sensor_types:SENSORS",
        ],
    },
)
