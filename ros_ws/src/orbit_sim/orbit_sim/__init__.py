"""Truth propagation (Kepler, Cowell two-body + J2, relative motion), frames, scenario handling, lock-step pacing and the MCAP recorder."""
