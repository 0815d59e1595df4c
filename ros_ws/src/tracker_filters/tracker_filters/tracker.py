"""A tracker above the single-target filter: detection sets in, tracks out (as Stone Soup's trackers).

For every detection set at time t:

1. predict each track's filter to t;
2. hypothesise: each track's predicted measurement and innovation covariance against every detection,
   gated by Mahalanobis distance (tracker_filters.association);
3. associate (global nearest neighbour by default; any ``DataAssociator``);
4. update each track with its detection through the filter's own guarded ``Filter.process`` (NaN/inf,
   out-of-order and failed updates rejected and rolled back), or let it coast on a miss (predicted only);
5. delete a track after ``max_misses`` consecutive misses (None: never);
6. initiate: when there is no track (none yet, or the last one deleted), a new one from the set's first
   unassociated detection (the sets arrive in random order) through the filter's initialiser. A detection-based
   initialiser (``first_scan``) can thus start on
   clutter; with clutter prefer a prior-based one (``given``, ``truth_scaled``), or set ``max_misses`` so a
   track started on clutter is dropped and started again.

The tracker holds at most one track (single target in clutter); the association layer already handles any
number. With a hard association (one detection, or none, per track) the tracker is exactly its filter: on a
set holding only the target's measurement it gives the filter's estimates bit for bit. A probabilistic
associator (JPDA) returns soft weights; it comes with a probabilistic update in ``update_track``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from tracker_filters.association import (
    NO_DETECTION,
    Association,
    DataAssociator,
    GlobalNearestNeighbour,
    Hypotheses,
    MahalanobisHypothesiser,
    measurement_prediction,
)
from tracker_filters.filter_base import Filter, StepResult

Initialise = Callable[[np.ndarray, np.ndarray, float], tuple[np.ndarray, np.ndarray]]
"""(z, R, t) -> (x0, P0): a track's prior from the detection that starts it."""


@dataclass
class Track:
    filter: Filter
    hits: int = 0
    misses: int = 0
    consecutive_misses: int = 0


@dataclass
class StepReport:
    """What the tracker did with one detection set (for logs and diagnostics)."""

    associations: list[Association] = field(default_factory=list)
    """One per track that existed before the step (empty on the step that starts a track)."""
    results: list[StepResult | None] = field(default_factory=list)
    """Per track: the filter's update result, None when it coasted."""
    hypotheses: Hypotheses | None = None
    rejected: list[str] = field(default_factory=list)
    started: bool = False
    deleted: int = 0

    @property
    def associated(self) -> list[int]:
        """The detection index of each track, NO_DETECTION for a miss."""
        return [a.detection for a in self.associations]


class Tracker:
    """Single-target tracking in clutter over any registered filter: ``new_filter()`` builds a fresh filter
    for a new track, ``initialise(z, R, t)`` gives its prior, ``model`` is the detections' measurement model."""

    max_tracks = 1

    def __init__(
        self,
        new_filter: Callable[[], Filter],
        initialise: Initialise,
        model,
        gate_probability: float = 0.999,
        associator: DataAssociator | None = None,
        max_misses: int | None = None,
    ) -> None:
        if max_misses is not None and max_misses < 1:
            raise ValueError(f"max_misses must be >= 1 or None, got {max_misses}")
        self.new_filter, self.initialise, self.model = new_filter, initialise, model
        self.hypothesiser = MahalanobisHypothesiser(gate_probability)
        self.associator = associator or GlobalNearestNeighbour()
        self.max_misses = max_misses
        self.tracks: list[Track] = []

    @property
    def gate_probability(self) -> float:
        return self.hypothesiser.gate_probability

    def step(self, t: float, Z: np.ndarray, R: np.ndarray) -> StepReport:
        """Process the detections Z (N, d), R (N, d, d) of time t (N may be 0)."""
        Z, R = np.asarray(Z, dtype=float), np.asarray(R, dtype=float)
        report = StepReport()
        if self.tracks:
            self._update(t, Z, R, report)
        used = {a.detection for a in report.associations}
        free = [j for j in range(len(Z)) if j not in used]
        if len(self.tracks) < self.max_tracks and free:
            self._start(t, Z[free[0]], R[free[0]], report)
        return report

    def _update(self, t: float, Z: np.ndarray, R: np.ndarray, report: StepReport) -> None:
        for track in self.tracks:
            if t > track.filter.t:
                track.filter.predict(t)
        predictions = [measurement_prediction(tr.filter, self.model, t) for tr in self.tracks]
        report.hypotheses = self.hypothesiser.hypothesise(predictions, Z, R, self.model)
        report.associations = self.associator.associate(report.hypotheses)
        for track, association in zip(self.tracks, report.associations):
            result = self.update_track(track, association, t, Z, R)
            report.results.append(result)
            if result is None:
                track.misses += 1
                track.consecutive_misses += 1
            elif result.accepted:
                track.hits += 1
                track.consecutive_misses = 0
            else:
                report.rejected.append(result.reason)
        if self.max_misses is not None:
            kept = [tr for tr in self.tracks if tr.consecutive_misses < self.max_misses]
            report.deleted = len(self.tracks) - len(kept)
            self.tracks = kept

    def update_track(
        self, track: Track, association: Association, t: float, Z: np.ndarray, R: np.ndarray
    ) -> StepResult | None:
        """Update one track with its association; None when it coasts (missed).

        A hard association updates through ``Filter.process`` with the chosen detection. Soft weights (PDA,
        JPDA) need a probabilistic update: pairing a soft associator with this tracker is a configuration error,
        reported as such; a tracker for such an associator overrides this method."""
        if not association.is_hard:
            raise TypeError(
                f"{type(self).__name__} updates with hard associations only, but the associator "
                "returned soft weights: use a tracker with a probabilistic update_track"
            )
        j = association.detection
        if j == NO_DETECTION:
            return None
        return track.filter.process(t, Z[j], R[j], self.model)

    def _start(self, t: float, z: np.ndarray, R: np.ndarray, report: StepReport) -> None:
        flt = self.new_filter()
        flt.initialise(*self.initialise(z, R, t), t)
        self.tracks.append(Track(flt, hits=1))
        report.started = True
