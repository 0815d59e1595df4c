"""Fixed-lag smoothing in the graph: the node kind ``fixed_lag`` for every entry of the scenario's
``fixed_lag_smoothers`` section that the run selects (``--estimators`` or the scenario's ``estimators``, like
any estimator); its source filter must be selected too.

    fixed_lag_smoothers:
      kf_a_lag: {source: kf_a, lag_s: 300.0}   # the estimate of each step once lag_s of later data is in

The node keeps the source filter's estimates of the last ``lag_s`` seconds. When an estimate arrives that is
at least ``lag_s`` after the oldest one kept, it runs the RTS backward pass (tracker_filters.smoothing) from
the newest estimate down to the oldest and publishes the oldest's smoothed estimate, stamped with its own
step and time. Each estimate's transition and gain (F_k x_k|k, P_k+1|k, C_k: filtered quantities only) are
computed once, as the next estimate arrives, and serve every window that holds it. For a linear-Gaussian
model the backward pass over that window gives exactly E[x_k | z_1..N] with N the newest measurement:
fixed-lag smoothing with a delay of at least ``lag_s``. The transitions come from the source filter's own
dynamics model. The last ``lag_s`` seconds of a run are not published (the node never learns that the run
ended; the offline ``rts`` estimator smooths them).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from bench_engine.config import ScenarioError
from bench_engine.graph import ESTIMATE_TYPE, NodeKind, NodeSpec, estimate_topic
from bench_engine.settings import POSITIVE, SectionReader, Settings, read_entries, setting
from bench_engine.stage import Estimate, Outputs, python_log
from tracker_filters.filter_settings import state_labels
from tracker_filters.filter_stage import build_stack

SECTION = "fixed_lag_smoothers"


@dataclass(frozen=True, kw_only=True)
class FixedLagConfig(Settings):
    """One entry of ``fixed_lag_smoothers``."""

    source: str = setting(doc="the filter (an entry of filters) whose estimates it smooths")
    lag_s: float = setting(
        unit="s", doc="each step's estimate is published once this much later data is in", check=POSITIVE
    )


def read_fixed_lag(cfg: dict) -> dict[str, FixedLagConfig]:
    """The ``fixed_lag_smoothers`` section, read strictly; each ``source`` is a filter of the scenario."""
    out = read_entries(FixedLagConfig, cfg.get(SECTION), SECTION)
    for conf in out.values():
        if conf.source not in (cfg.get("filters") or {}):
            raise ScenarioError(f"'{conf.where('source')}' must name a filter of the scenario, got {conf.source!r}")
    return out


FIXED_LAG_SMOOTHERS = SectionReader(
    SECTION,
    dict[str, FixedLagConfig],
    "fixed-lag smoothers of filters' estimates in the graph (node kind fixed_lag: estimators)",
    read_fixed_lag,
)


class FixedLagSmoother:
    """The node's core: a window of the source filter's estimates, smoothed backwards on every arrival."""

    def __init__(self, cfg: dict, name: str, run: dict | None = None) -> None:
        self.name, self.conf = name, read_fixed_lag(cfg)[name]
        self.dynamics = build_stack(cfg, self.conf.source).filter.dynamics
        self.window: deque[Estimate] = deque()
        self.gains: deque[tuple[np.ndarray, ...]] = deque()
        """The RTS gain (tracker_filters.smoothing.rts_gain) from each estimate of the window to the next."""
        self.topic = estimate_topic(name)
        self.log = python_log(name)

    def on_input(self, topic: str, e: Estimate) -> Outputs:
        if self.window and e.t_ns <= self.window[-1].t_ns:
            self.log("warning", f"ignored an estimate of step {e.step} that is not newer than the last")
            return []
        from tracker_filters.smoothing import rts_gain  # scipy: not for every node reading the kind

        if self.window:
            last = self.window[-1]
            x, P, dt = np.asarray(last.x, dtype=float), np.asarray(last.P, dtype=float), (e.t_ns - last.t_ns) * 1e-9
            self.gains.append(
                rts_gain(
                    x,
                    P,
                    np.asarray(self.dynamics.transition_matrix(x, dt), dtype=float),
                    np.asarray(self.dynamics.process_noise(x, dt), dtype=float),
                )
            )
        self.window.append(e)
        out = []
        while len(self.window) > 1 and (self.window[-1].t_ns - self.window[0].t_ns) * 1e-9 >= self.conf.lag_s:
            out.append((self.topic, self._smoothed_oldest()))
            self.window.popleft()
            self.gains.popleft()
        return out

    def _smoothed_oldest(self) -> Estimate:
        """RTS backward pass (tracker_filters.smoothing.rts_step) from the newest estimate of the window to the
        oldest."""
        from tracker_filters.smoothing import rts_step  # scipy.linalg: not for every node reading the kind

        items = list(self.window)
        x_s, P_s = np.asarray(items[-1].x, dtype=float), np.asarray(items[-1].P, dtype=float)
        for e, gain in zip(reversed(items[:-1]), reversed(self.gains)):
            x_s, P_s = rts_step(np.asarray(e.x, dtype=float), np.asarray(e.P, dtype=float), gain, x_s, P_s)
        oldest = items[0]
        return Estimate(
            oldest.step,
            oldest.t_ns,
            oldest.frame_id,
            self.name,
            list(oldest.labels),
            x_s,
            P_s,
            oldest.nis,
            {"lag_s": (items[-1].t_ns - oldest.t_ns) * 1e-9},
        )


def _spec(cfg: dict, name: str) -> NodeSpec:
    conf = read_fixed_lag(cfg)[name]
    return NodeSpec(
        name,
        "fixed_lag",
        publishes={estimate_topic(name): ESTIMATE_TYPE},
        subscribes={estimate_topic(conf.source): ""},
        labels={estimate_topic(name): state_labels(cfg, conf.source)},
    )


FIXED_LAG = NodeKind(
    "fixed_lag",
    "estimator",
    "bench_engine.stage_node:StageNode",
    instances=lambda cfg, names: list(names),
    spec=_spec,
    check=lambda cfg, name: FixedLagSmoother(cfg, name),
    stage=FixedLagSmoother,
    order=1,
    claims=lambda cfg: list(read_fixed_lag(cfg)),
)
