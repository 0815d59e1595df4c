"""Codecs between measurement items (bench_engine.stage.Measurement, DetectionSet) and their ROS messages.

Registered per message type in the entry-point group ``tracking_bench.codecs``: RangeAzEl (range, azimuth,
elevation, optional range rate, 4x4 covariance), VectorMeasurement (labelled vector + covariance) and
DetectionSet (a set of labelled vectors with their covariances).
"""

from __future__ import annotations

import numpy as np

from bench_engine.stage import DetectionSet, Measurement, set_stamp, stamp_ns

RANGE_AZ_EL_LABELS = ("range", "azimuth", "elevation", "range_rate")


class RangeAzElCodec:
    def encode(self, item: Measurement, msg_type: type):
        msg = msg_type()
        set_stamp(msg, item)
        msg.sensor_id = item.source
        z = item.z
        msg.range, msg.azimuth, msg.elevation = (float(v) for v in z[:3])
        msg.has_range_rate = len(z) > 3
        msg.range_rate = float(z[3]) if msg.has_range_rate else float("nan")
        cov = np.zeros((4, 4))
        cov[: len(z), : len(z)] = item.R
        msg.covariance = cov.ravel()
        return msg

    def measurement_vectors(self, table) -> np.ndarray | None:
        """The z of every message of a topic read as columns (bench_engine.columns.Table), one row each, as
        ``decode`` gives them; None when some have a range rate and others not."""
        has = np.asarray(table["has_range_rate"], dtype=bool)
        if len(has) and has.any() != has.all():
            return None
        names = ["range", "azimuth", "elevation"] + (["range_rate"] if len(has) and has[0] else [])
        return np.column_stack([np.asarray(table[n], dtype=float) for n in names]).reshape(len(has), len(names))

    def decode(self, msg) -> Measurement:
        d = 4 if msg.has_range_rate else 3
        z = np.array([msg.range, msg.azimuth, msg.elevation, msg.range_rate][:d])
        R = np.asarray(msg.covariance, dtype=float).reshape(4, 4)[:d, :d].copy()
        return Measurement(
            msg.step, stamp_ns(msg), msg.header.frame_id, msg.sensor_id, z, R, list(RANGE_AZ_EL_LABELS[:d])
        )


class VectorMeasurementCodec:
    def encode(self, item: Measurement, msg_type: type):
        msg = msg_type()
        set_stamp(msg, item)
        msg.sensor_id = item.source
        msg.labels = list(item.labels)
        msg.value = np.asarray(item.z, dtype=float).tolist()
        msg.covariance = np.asarray(item.R, dtype=float).ravel().tolist()
        return msg

    def measurement_vectors(self, table) -> np.ndarray | None:
        """The z of every message of a topic read as columns (bench_engine.columns.Table), one row each, as
        ``decode`` gives them; None when their lengths differ."""
        value = table["value"]
        return value.astype(float) if isinstance(value, np.ndarray) and value.ndim == 2 else None

    def decode(self, msg) -> Measurement:
        z = np.asarray(msg.value, dtype=float)
        return Measurement(
            msg.step,
            stamp_ns(msg),
            msg.header.frame_id,
            msg.sensor_id,
            z,
            np.asarray(msg.covariance, dtype=float).reshape(len(z), len(z)),
            list(msg.labels),
        )


RANGE_AZ_EL = RangeAzElCodec()
VECTOR_MEASUREMENT = VectorMeasurementCodec()


class DetectionSetCodec:
    """bench_msgs/DetectionSet <-> DetectionSet (detection i: values[i d:(i+1) d], covariance d x d each)."""

    def encode(self, item: DetectionSet, msg_type: type):
        msg = msg_type()
        set_stamp(msg, item)
        msg.sensor_id = item.source
        msg.labels = list(item.labels)
        msg.values = np.asarray(item.Z, dtype=float).ravel().tolist()
        msg.covariance = np.asarray(item.R, dtype=float).ravel().tolist()
        return msg

    def decode(self, msg) -> DetectionSet:
        d = len(msg.labels)
        Z = np.asarray(msg.values, dtype=float).reshape(-1, d)
        return DetectionSet(
            msg.step,
            stamp_ns(msg),
            msg.header.frame_id,
            msg.sensor_id,
            list(msg.labels),
            Z,
            np.asarray(msg.covariance, dtype=float).reshape(len(Z), d, d),
        )


DETECTION_SET = DetectionSetCodec()
