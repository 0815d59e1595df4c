"""State and measurement component labels: the one definition of the names the bench gives positions,
velocities, attitude quaternions, angular rates and angles.

A component is known by its label everywhere: the truth and every estimate carry their labels, the views find
a pose in them (bench_engine.views), an error is taken by the labels' kind (bench_models.states: a quaternion
block as a rotation vector, an angle wrapped to (-pi, pi]), and a measurement model's angles are the
components whose labels are angles (bench_models.models.check_angles).

Angles: :data:`ANGLES` are the built-in angle labels. A plugin whose state or measurement has an angle of
another name registers it in the entry-point group ``tracking_bench.angle_labels``, the entry point's name being
the label and its value the module that defines the component (for the reader; it is not loaded)::

    entry_points={"tracking_bench.angle_labels": ["bearing = my_plugin.bearing_sensor"]}

:func:`angle_labels` is the built-in and registered ones together.
"""

from __future__ import annotations

from functools import lru_cache

from bench_engine import plugins

POSITION = ("x", "y", "z")
VELOCITY = ("vx", "vy", "vz")
ORBIT = POSITION + VELOCITY
"""A position-velocity state (an orbit in ECI, relative motion in LVLH)."""
BIAS = ("bx", "by", "bz")
"""A constant acceleration bias in LVLH (the CW+bias relative-motion state: ORBIT + BIAS)."""
QUATERNION = ("qw", "qx", "qy", "qz")
"""An attitude quaternion, scalar first (Hamilton; rotating the reference frame into the body frame)."""
ROTATION = ("rx", "ry", "rz")
"""The error of a quaternion block: a rotation vector [rad]. An attitude estimate's covariance is over it (the
quaternion's labels replaced by these at qw's place: bench_models.states.error_labels)."""
ANGULAR_RATE = ("wx", "wy", "wz")
"""Body angular rate [rad/s]."""
ANGLES = frozenset({"azimuth", "elevation", "roll", "pitch", "yaw", "phase", "angle"})
"""The built-in angle labels: a component with one of these is an angle, differenced with wrapping to
(-pi, pi]."""
AZIMUTHS = frozenset({"azimuth"})
"""Angles a sensor reports in [0, 2 pi) (bench_msgs/RangeAzEl), not (-pi, pi]."""


@lru_cache(maxsize=1)
def angle_labels() -> frozenset[str]:
    """Every angle label: :data:`ANGLES` and those registered under ``tracking_bench.angle_labels``."""
    return ANGLES | frozenset(plugins.names("angle_labels"))
