"""A tracker above the single-target filter: detection sets in, tracks out (as Stone Soup's trackers).

Each step: predict every track's filter to the detections' time, hypothesise and gate every (track, detection)
pair, associate (tracker_filters.association), then update each track's filter with its detection through the
filter's own guarded ``process`` (NaN/inf, out-of-order and failed updates rejected), or let it coast on a miss.
A track is started from the first non-empty detection set by the filter's initialiser (for a detection-based
initialiser, from that set's first detection: with clutter, use a prior-based one such as ``given``).
This is a single-target tracker in clutter (``max_tracks`` = 1); the layer is where multi-target trackers and
probabilistic associators (JPDA) plug in.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from tracker_filters.association import NO_DETECTION, DataAssociator, GlobalNearestNeighbour, hypothesise
from tracker_filters.filter_base import Filter


@dataclass
class Track:
    filter: Filter
    hits: int = 0
    misses: int = 0


@dataclass
class StepReport:
    """What the tracker did with one detection set (for logs and diagnostics)."""

    associated: list[int] = field(default_factory=list)
    rejected: list[str] = field(default_factory=list)
    started: bool = False


class Tracker:
    """Single-target tracking in clutter: ``new_filter()`` builds a fresh filter, ``initialise(z, R, t)`` gives
    its prior (x0, P0)."""

    def __init__(self, new_filter: Callable[[], Filter], initialise: Callable, model,
                 gate_probability: float = 0.999, associator: DataAssociator | None = None) -> None:
        if not 0.0 < gate_probability < 1.0:
            raise ValueError(f"gate_probability must be in (0, 1), got {gate_probability}")
        self.new_filter, self.initialise, self.model = new_filter, initialise, model
        self.gate_probability = gate_probability
        self.associator = associator or GlobalNearestNeighbour()
        self.tracks: list[Track] = []

    def step(self, t: float, Z: np.ndarray, R: np.ndarray) -> StepReport:
        """Process the detections Z (N, d), R (N, d, d) of time t."""
        report = StepReport()
        if not self.tracks:
            if len(Z):
                flt = self.new_filter()
                flt.initialise(*self.initialise(Z[0], R[0], t), t)
                self.tracks.append(Track(flt, hits=1))
                report.started = True
            return report
        for track in self.tracks:
            if t > track.filter.t:
                track.filter.predict(t)
        hyp = hypothesise([tr.filter.x for tr in self.tracks], [tr.filter.P for tr in self.tracks], Z, R, self.model,
                          t, self.gate_probability)
        report.associated = self.associator.associate(hyp)
        for track, j in zip(self.tracks, report.associated):
            if j == NO_DETECTION:
                track.misses += 1
                continue
            result = track.filter.process(t, Z[j], R[j], self.model)
            if result.accepted:
                track.hits += 1
            else:
                report.rejected.append(result.reason)
        return report
