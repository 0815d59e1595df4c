"""The scoring window: the part of each run over which every estimator of a study is scored, stated once in the
scenario's ``scoring`` section and applied by the scorer (bench_eval.scoring), never per estimator:

    scoring:
      window:
        head_s: 3600.0    # s at the run's start left out of the scores (default 0)
        tail_s: 3600.0    # s at the run's end left out (default 0)
        edges: true       # also score the head and the tail, each apart (default false)

A run spans its truth's first to last time [t0, t1]; the window is [t0 + head_s, t1 - tail_s]. The scorer runs
the offline estimators and the bounds over the whole run first (a smoother, a differentiator or an orbit fit uses
the data on both sides of the window), then keeps, of every scored estimator, the steps of the window at which
every scored estimator of the run has a finite estimate: all are scored over the same steps, whatever their own
spans and rates (a fixed-lag smoother lacks a run's last ``lag_s``, an orbit fit estimates at every truth step, a
filter at its measurements' steps). The run's measurements and bound series are cut to the window as well. An
estimator without any estimate in the window is not scored (a warning names it).

With ``edges``, the head [t0, t0 + head_s) and the tail (t1 - tail_s, t1] are scored the same way, each estimator
over its own steps there (one may not cover all of an edge), and each estimator's score block gets
``edges: {head: {...}, tail: {...}}``, the metric family's scores there: what each does at the ends of its arc,
where a smoother has data on one side only and a causal filter starts up.

Without the key every estimator is scored over all of its own steps.
"""

from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass

import numpy as np

from bench_engine.config import ScenarioError
from bench_engine.settings import NON_NEGATIVE, Settings, read, setting
from bench_engine.timegrid import Time
from bench_eval.bag_data import BagData, Estimates

EDGES = ("head", "tail")


@dataclass(frozen=True, kw_only=True)
class ScoringWindow(Settings):
    """``scoring.window``: the part of each run every estimator is scored over (module docstring)."""

    head_s: float = setting(0.0, unit="s", check=NON_NEGATIVE, doc="left out of the scores at the run's start")
    tail_s: float = setting(0.0, unit="s", check=NON_NEGATIVE, doc="left out of the scores at the run's end")
    edges: bool = setting(False, doc="also score the head and the tail, each apart, into each score block's 'edges'")

    def inside(self, t: np.ndarray, t0: float, t1: float, part: str = "window") -> np.ndarray:
        """Which of the times ``t`` lie in ``part`` (``window``, ``head`` or ``tail``) of an arc [t0, t1]."""
        lo, hi = t0 + self.head_s, t1 - self.tail_s
        t = np.asarray(t, dtype=float)
        return {"window": (t >= lo) & (t <= hi), "head": (t >= t0) & (t < lo), "tail": (t > hi) & (t <= t1)}[part]

    def cut(self, data: BagData, scored: list[str], part: str = "window") -> tuple[BagData, list[str]]:
        """``data`` restricted to ``part`` of the run (its truth's span), and the estimators scored there: in the
        window, the steps where every scored estimator has a finite estimate; in an edge, each one's own steps."""
        t0, t1 = data.truth_span()

        def inside(t: np.ndarray) -> np.ndarray:
            return self.inside(t, t0, t1, part)

        estimates = {name: _rows(est, inside(est.t)) for name, est in data.estimates.items()}
        having = [n for n in scored if n in estimates and np.any(_finite(estimates[n]))]
        if part == "window":
            for name in sorted(set(scored) - set(having)):
                print(
                    f"[score] '{name}' has no estimate in the scoring window [{t0 + self.head_s:g}, "
                    f"{t1 - self.tail_s:g}] s of {data.run.get('bag_dir', 'a run')}: not scored",
                    file=sys.stderr,
                )
            common = _common_steps([estimates[n] for n in having])
            for name in having:
                estimates[name] = _rows(estimates[name], np.isin(estimates[name].steps, common))
        else:
            for name in having:
                estimates[name] = _rows(estimates[name], _finite(estimates[name]))
        measurements = {}
        for sensor, by_step in data.measurements.items():
            steps = np.fromiter(by_step, dtype=np.int64, count=len(by_step))
            covered, t, _ = data.truth_at(steps)
            measurements[sensor] = {k: by_step[k] for k in steps[covered][inside(t)].tolist()}
        bounds = {name: _bound_rows(series, inside(series.t)) for name, series in (data.bounds or {}).items()}
        return dataclasses.replace(data, estimates=estimates, measurements=measurements, bounds=bounds), having


def check_window(window: ScoringWindow | None, cfg: dict) -> None:
    """ScenarioError unless head_s + tail_s leave part of the run's ``time.duration``."""
    if window is None:
        return
    duration = read(Time, cfg.get("time"), "time").duration
    if window.head_s + window.tail_s >= duration:
        raise ScenarioError(
            f"'{window.where('head_s')}' + '{window.where('tail_s')}' = "
            f"{window.head_s + window.tail_s:g} s leaves nothing of the run's {duration:g} s "
            "(time.duration): shorten them, e.g. --set scoring.window.head_s=0 --set "
            "scoring.window.tail_s=0"
        )


def _finite(est: Estimates) -> np.ndarray:
    return np.all(np.isfinite(est.x), axis=1) if len(est.steps) else np.zeros(0, bool)


def _common_steps(estimates: list[Estimates]) -> np.ndarray:
    """The steps at which every one of ``estimates`` has a finite state."""
    common = None
    for est in estimates:
        steps = est.steps[_finite(est)]
        common = steps if common is None else np.intersect1d(common, steps)
    return np.zeros(0, np.int64) if common is None else common


def _rows(est: Estimates, keep: np.ndarray) -> Estimates:
    keep = _slice(keep)
    return dataclasses.replace(
        est,
        steps=est.steps[keep],
        t=est.t[keep],
        x=est.x[keep],
        P=est.P[keep],
        diagnostics={k: v[keep] for k, v in est.diagnostics.items()},
        nis=None if est.nis is None else est.nis[keep],
    )


def _bound_rows(series, keep: np.ndarray):
    keep = _slice(keep)
    return dataclasses.replace(series, steps=series.steps[keep], t=series.t[keep], P=series.P[keep])


def _slice(keep: np.ndarray) -> np.ndarray | slice:
    """The rows a mask keeps as a slice when they are evenly spaced (a window of a run's sorted steps, or every
    other step where another estimator runs at half the rate: views, not copies of the covariances), else the
    mask."""
    rows = np.flatnonzero(keep)
    if len(rows) < 2:
        return keep
    stride = int(rows[1] - rows[0])
    return slice(int(rows[0]), int(rows[-1]) + 1, stride) if np.all(np.diff(rows) == stride) else keep
