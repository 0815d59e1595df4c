"""An in-process run (bench_engine.inprocess) as the scorer's BagData, so that tests and scripts score runs with
the bench's own metric code (bench_eval.scoring, the studies' metric families) without ROS or a bag on disk."""

from __future__ import annotations

import numpy as np

from bench_engine.graph import ESTIMATE, MEASUREMENT, TRUTH_TOPIC, topic_owner
from bench_engine.inprocess import run_in_process
from bench_engine.stage import Estimate, Measurement
from bench_eval.scoring import BagData, Estimates


def bag_data(cfg: dict, filters: list[str] | None, seed: int) -> BagData:
    """Run ``cfg`` in process with ``filters`` and ``seed``; return what the scorer would read from its bag:
    truth, measurements (sensor -> step -> z, of a Measurement or any sensor item with ``z``, e.g. a star frame's
    centroids) and every estimator's estimates in step order."""
    run = run_in_process(cfg, filters, seed=seed)
    estimators = [spec.name for spec in run.graph.of_role("estimator")]
    data = BagData({"scenario": {**cfg, "seed": int(seed)}, "estimators": estimators})
    truth = run.items[TRUTH_TOPIC]
    data.truth = {s.step: (s.t, np.asarray(s.state, dtype=float)) for s in truth}
    data.truth_labels = list(truth[-1].labels)
    for topic, items in run.items.items():
        sensor, estimator = topic_owner(topic, MEASUREMENT), topic_owner(topic, ESTIMATE)
        if sensor is not None and items and (isinstance(items[0], Measurement) or hasattr(items[0], "z")):
            data.measurements[sensor] = {m.step: np.asarray(m.z, dtype=float) for m in items}
        elif estimator is not None and items and isinstance(items[0], Estimate):
            data.estimates[estimator] = estimates(items)
    return data


def estimates(items: list[Estimate]) -> Estimates:
    """One estimator's Estimate items as the scorer's columns (in step order)."""
    items = sorted(items, key=lambda e: e.step)
    names = sorted(set().union(*(e.diagnostics for e in items)))
    return Estimates(
        np.array([e.step for e in items], dtype=np.int64),
        np.array([e.t for e in items]),
        np.array([e.x for e in items], dtype=float),
        np.array([e.P for e in items], dtype=float),
        list(items[0].labels),
        {k: np.array([e.diagnostics.get(k, np.nan) for e in items], dtype=float) for k in names},
    )
