"""The scorer's own failure, in a module light enough for every command to import before it knows it will
score (bench_eval.scoring pulls in the metrics and scipy)."""

from __future__ import annotations


class NothingToScore(ValueError):
    """The bags hold no estimate of any of their run's estimators."""
