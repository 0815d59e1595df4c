"""The star tracker's item and its codec: bench_msgs/StarCentroids <-> :class:`StarFrame` (registered in
``tracking_bench.codecs``). One type for three kinds of topic (the .msg file): a camera's measured centroids,
its per-centroid truth (scoring only, its own topic) and an estimator's identification of the centroids.
Positions travel as tangent-plane coordinates (camera.py: to_tangent / from_tangent).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bench_engine.stage import Item, set_stamp, stamp_ns

STAR_CENTROIDS_TYPE = "bench_msgs/msg/StarCentroids"


def star_truth_topic(camera: str) -> str:
    """A star camera's per-centroid truth topic (scoring only)."""
    return f"/{camera}/star_truth"


@dataclass
class StarFrame(Item):
    """One frame's centroids: tangent-plane positions ``xy`` (N, 2), magnitudes (N,) or empty, the 1σ noise
    per axis (tangent units), the gyro's body rate over the interval since the previous frame (rad/s, camera
    frame) and its boresight jitter part, and per-centroid star ids (empty on measurement topics)."""

    source: str = ""
    xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    magnitudes: np.ndarray = field(default_factory=lambda: np.zeros(0))
    sigma: float = 0.0
    body_rate: np.ndarray = field(default_factory=lambda: np.zeros(3))
    jitter_rate: float = 0.0
    star_id: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @property
    def z(self) -> np.ndarray:
        """The positions as one vector (x0, y0, x1, y1, ...): what the scorer keeps of a measurement topic."""
        return self.xy.ravel()


class StarCentroidsCodec:
    def encode(self, item: StarFrame, msg_type: type):
        msg = msg_type()
        set_stamp(msg, item)
        msg.camera_id = item.source
        xy = np.asarray(item.xy, dtype=float).reshape(-1, 2)
        msg.x, msg.y = xy[:, 0].tolist(), xy[:, 1].tolist()
        msg.magnitude = np.asarray(item.magnitudes, dtype=float).tolist()
        msg.sigma = float(item.sigma)
        msg.body_rate = [float(v) for v in item.body_rate]
        msg.jitter_rate = float(item.jitter_rate)
        msg.star_id = [int(v) for v in item.star_id]
        return msg

    def decode(self, msg) -> StarFrame:
        return StarFrame(
            msg.step,
            stamp_ns(msg),
            msg.header.frame_id,
            msg.camera_id,
            np.column_stack([np.asarray(msg.x, dtype=float), np.asarray(msg.y, dtype=float)]),
            np.asarray(msg.magnitude, dtype=float),
            float(msg.sigma),
            np.asarray(msg.body_rate, dtype=float),
            float(msg.jitter_rate),
            np.asarray(msg.star_id, dtype=np.int64),
        )


STAR_CENTROIDS = StarCentroidsCodec()
