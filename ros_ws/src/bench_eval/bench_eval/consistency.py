"""Scores that need no truth: what a run on real tracking data (an imported TDM, bench_ccsds) can be judged by.

Per estimator, pooled over the runs (``innovations`` block of its scores):
- ``nis_mean`` over its updates, its measurement dimension ``nis_dof`` and the 95 % two-sided band of the mean of
  that many independent chi-square(dof) values (a consistent filter's innovations are white, so its NIS are
  independent: Bar-Shalom, Li & Kirubarajan 2001, sec. 5.4.2), and ``nis_fraction_inside`` the fraction of
  single NIS inside the 95 % two-sided chi-square(dof) interval;
- ``residuals``: per sensor, the post-fit residuals z_k - h(x_k|k) (angles wrapped): their RMS per component in
  SI units (m, rad, m/s) and divided by the measurement's standard deviation (below 1 for an estimate that
  absorbed some of each measurement's noise);
- ``sigma_position``: the convergence of the estimator's own position uncertainty sqrt(tr P_xyz) by the rule the
  RMSE's convergence uses (bench_eval.metrics.summarise: the first time it stays below 1.5 times its level over
  the last half of the run), with its peak and converged level [m].
"""

from __future__ import annotations

import numpy as np
from scipy.special import chdtri

from bench_eval.metrics import json_ready, summarise
from tracker_filters.builders import build_filter_stack

LEVEL = 0.05
POSITION = ("x", "y", "z")

TRUTHLESS = "innovations (no truth)"
"""The ``metric`` of a score without truth (bench_eval.scoring): no registered family, bench_eval.consistency's
scores instead."""


def score_without_truth(scenario: str, runs: list, with_series: bool):
    """A run without truth (an imported TDM without reference, bench_ccsds): scored by what needs none, the
    innovations, post-fit residuals and the estimators' own convergence (innovation_scores); with
    ``with_series``, paired with no series, as bench_eval.scoring.score_bags returns them."""
    result = {"scenario": scenario, "runs": len(runs), "metric": TRUTHLESS, "estimators": innovation_scores(runs)}
    return (result, {}) if with_series else result


def innovation_scores(runs: list) -> dict[str, dict]:
    """{estimator: {"innovations": {...}}} for every run filter with estimates in ``runs`` (loaded bags:
    bench_eval.bag_data.BagData)."""
    names = [
        n
        for n in dict.fromkeys(n for d in runs for n in d.run.get("estimators", []))
        if any(n in d.estimates for d in runs)
    ]
    return {
        name: {"innovations": json_ready(_scores(name, [d for d in runs if name in d.estimates]))} for name in names
    }


def _scores(name: str, runs: list) -> dict:
    nis, dofs, residuals, sigmas = [], [], {}, []
    t0 = min(float(d.estimates[name].t[0]) for d in runs)
    for data in runs:
        est = data.estimates[name]
        stack = build_filter_stack(data.scenario, name)
        by_step = {s: data.measurements.get(s, {}) for s in stack.sensors}
        for s, sensor in stack.sensors.items():
            rows = [i for i, k in enumerate(est.steps) if int(k) in by_step[s]]
            if not rows:
                continue
            z = np.array([by_step[s][int(est.steps[i])] for i in rows])
            r = z - sensor.model.h_series(est.x[rows], est.t[rows])
            for i in sensor.model.angle_indices:
                r[:, i] = np.angle(np.exp(1j * r[:, i]))
            residuals.setdefault(s, []).append((r, np.sqrt(np.diag(sensor.R)), list(sensor.model.labels)))
        if est.nis is not None:
            for i, k in enumerate(est.steps):
                seen = [s for s in stack.sensors if int(k) in by_step[s]]
                if len(seen) == 1 and np.isfinite(est.nis[i]):
                    nis.append(float(est.nis[i]))
                    dofs.append(len(stack.sensors[seen[0]].model.labels))
        if all(c in est.labels for c in POSITION):
            idx = [est.labels.index(c) for c in POSITION]
            sigmas.append((est.t, np.sqrt(np.trace(est.P[:, idx][:, :, idx], axis1=1, axis2=2))))
    out: dict = {"runs": len(runs), "updates": len(nis)}
    if nis:
        values, dof = np.array(nis), np.array(dofs)
        n, k = len(values), int(np.round(np.mean(dof)))
        inside = (values >= chdtri(dof, 1.0 - 0.5 * LEVEL)) & (values <= chdtri(dof, 0.5 * LEVEL))
        out.update(
            nis_mean=float(np.mean(values)),
            nis_dof=float(np.mean(dof)),
            nis_band=[chdtri(n * k, 1.0 - 0.5 * LEVEL) / n, chdtri(n * k, 0.5 * LEVEL) / n],
            nis_fraction_inside=float(np.mean(inside)),
        )
    out["residuals"] = {}
    for s, parts in residuals.items():
        r = np.vstack([p[0] for p in parts])
        sd = parts[0][1]
        labels = parts[0][2]
        out["residuals"][s] = {
            "count": len(r),
            "rms": dict(zip(labels, np.sqrt(np.mean(r**2, axis=0)))),
            "rms_normalised": dict(zip(labels, np.sqrt(np.mean((r / sd) ** 2, axis=0)))),
        }
    if sigmas:
        t = np.concatenate([s[0] for s in sigmas])
        sd = np.concatenate([s[1] for s in sigmas])
        order = np.argsort(t, kind="stable")
        summary = summarise(t[order], sd[order], t0=t0)
        out["sigma_position"] = {
            "peak_m": summary["peak"],
            "convergence_time_s": summary["convergence_time_s"],
            "converged_m": summary["converged"],
        }
    return out
