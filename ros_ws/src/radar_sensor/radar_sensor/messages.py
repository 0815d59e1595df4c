"""Conversions between measurement vectors and their ROS messages (RangeAzEl, VectorMeasurement)."""
from __future__ import annotations

import numpy as np

from bench_msgs.msg import RangeAzEl, VectorMeasurement


def _stamp(msg, t_ns: int, frame_id: str, step: int, sensor_id: str) -> None:
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(t_ns), 1_000_000_000)
    msg.header.frame_id = frame_id
    msg.step = int(step)
    msg.sensor_id = sensor_id


def to_message(msg_type: type, z: np.ndarray, R: np.ndarray, labels, t_ns: int, frame_id: str, step: int,
               sensor_id: str):
    """Build a measurement message of ``msg_type`` carrying z and its covariance R."""
    msg = msg_type()
    _stamp(msg, t_ns, frame_id, step, sensor_id)
    if msg_type is RangeAzEl:
        msg.range, msg.azimuth, msg.elevation = (float(v) for v in z[:3])
        msg.has_range_rate = len(z) > 3
        msg.range_rate = float(z[3]) if msg.has_range_rate else float("nan")
        cov = np.zeros((4, 4))
        cov[: len(z), : len(z)] = R
        msg.covariance = cov.ravel()
    else:
        msg.labels = list(labels)
        msg.value = np.asarray(z, dtype=float).tolist()
        msg.covariance = np.asarray(R, dtype=float).ravel().tolist()
    return msg


def from_message(msg) -> tuple[float, np.ndarray, np.ndarray]:
    """(t [s], z, R) of a measurement message."""
    t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
    if isinstance(msg, RangeAzEl):
        d = 4 if msg.has_range_rate else 3
        z = np.array([msg.range, msg.azimuth, msg.elevation, msg.range_rate][:d])
        R = np.asarray(msg.covariance, dtype=float).reshape(4, 4)[:d, :d].copy()
        return t, z, R
    z = np.asarray(msg.value, dtype=float)
    return t, z, np.asarray(msg.covariance, dtype=float).reshape(len(z), len(z))


MESSAGE_CLASSES = {"bench_msgs/msg/RangeAzEl": RangeAzEl, "bench_msgs/msg/VectorMeasurement": VectorMeasurement}
