"""The star tracker's choices, by name (cheap to import: the tracker node kind reads them to check a scenario,
and every node of a run reads every node kind; the per-frame core, star_tracker.pipeline, implements them)."""

TRACKERS = ("sna", "jpdaf")
"""Star tracking: the SNA (nearest neighbour in the predicted window) or the JPDAF."""
SOLVERS = ("wahba", "triad")
"""Attitude from the tracked stars: all stars (SVD Wahba) or TRIAD on two."""
MOTIONS = ("constant_velocity", "coordinated_turn")
"""The JPDAF's image-plane motion model."""
BORESIGHTS = ("zenith", "normal")
"""The camera's boresight in LVLH (sky_motion.py): zenith (a straight drift across the sky) or orbit normal (a
rotation about the boresight)."""
AIDS = ("rate", "jitter", "none")
"""What the body rate compensates in the JPDAF's prediction (pipeline.StarTrackerPipeline.motion_for)."""
