"""Unmodelled acceleration of each filter's relative-motion model against the scenario's nonlinear truth.

For a formation scenario (paper 004, ``formation_cqkf``) the truth is the full two-body + J2 motion of both
spacecraft, expressed in the chief's LVLH frame; each filter's dynamics model is linear, x' = A x. Sampling
the truth every second over the scenario's duration, the truth's relative acceleration (central finite
differences of its rotating-frame velocity, error O(dt^2 n^2)) minus the model's A x is the acceleration the
model leaves unmodelled: the process noise has to cover it. Per model and LVLH axis (radial, along-track,
cross-track): its RMS and maximum, and the RMS one-step position prediction error x(t+T) - Phi(T) x(t) over
the sample intervals T = 1 s and 10 s. For CW+bias the best constant bias (the orbit mean of the CW
residual) is removed first: a lower bound on what a constant bias can absorb.
"""

from __future__ import annotations

import numpy as np

from bench_engine.config import ScenarioError, apply_overrides
from bench_engine.graph import resolve_estimators
from orbit_sim.truth import build_truth
from tracker_filters.builders import build_dynamics
from tracker_filters.filter_settings import filter_key

INTERVALS_S = (1.0, 10.0)
"""Sample intervals of the one-step prediction error (the paper's 1 s and 10 s)."""
AXES = ("x", "y", "z")
UM = 1e6  # m/s^2 -> um/s^2
MM = 1e3  # m -> mm


def relative_truth(cfg: dict, dt: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The scenario's truth (times (K,), LVLH states (K, 6)) resampled every ``dt`` seconds."""
    truth = build_truth(apply_overrides(cfg, [f"time.dt={dt}"]))
    if truth.frame != "lvlh":
        raise ScenarioError(f"model errors need a relative (lvlh) truth, the scenario's is '{truth.frame}'")
    return truth.grid.times(), np.asarray(truth.states)


def filter_dynamics(cfg: dict) -> dict[str, object]:
    """Each default filter's dynamics model, built exactly as the filter node builds it."""
    return {name: build_dynamics(filter_key(cfg, name, "dynamics"), cfg) for name in resolve_estimators(cfg, None)}


def truth_acceleration(t: np.ndarray, states: np.ndarray) -> np.ndarray:
    """Rotating-frame relative acceleration at the interior samples, central differences (K - 2, 3)."""
    return (states[2:, 3:6] - states[:-2, 3:6]) / (t[2:] - t[:-2])[:, None]


def model_residual(model, t: np.ndarray, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(truth acceleration - model acceleration at the interior samples (K - 2, 3), the model's extra
    constant states: the best constant bias for a 9-state bias model, empty otherwise)."""
    A = np.asarray(model.A)
    residual = truth_acceleration(t, states) - states[1:-1, 0:6] @ A[3:6, 0:6].T
    extra = len(model.labels) - 6
    if extra == 0:
        return residual, np.zeros(0)
    bias = residual.mean(axis=0)
    return residual - A[3:6, 6:] @ bias, bias


def prediction_error(model, t: np.ndarray, states: np.ndarray, extra: np.ndarray, interval: float) -> float:
    """RMS of |r(t + T) - [Phi(T) x(t)]_r| over the run [m] (T a multiple of the truth's sampling)."""
    m = int(round(interval / (t[1] - t[0])))
    x = np.hstack((states[:-m], np.broadcast_to(extra, (len(states) - m, len(extra)))))
    predicted = x @ np.asarray(model.transition_matrix(None, interval)).T
    return float(np.sqrt(np.mean(np.sum((predicted[:, 0:3] - states[m:, 0:3]) ** 2, axis=1))))


def model_error_rows(label: str, cfg: dict, intervals: tuple[float, ...] = INTERVALS_S) -> list[dict]:
    """One row per filter model of the case: RMS and max |residual| per axis [m/s^2], prediction errors [m]."""
    t, states = relative_truth(cfg)
    rows = []
    for name, model in filter_dynamics(cfg).items():
        residual, extra = model_residual(model, t, states)
        rows.append(
            {
                "case": label,
                "filter": name,
                "model": filter_key(cfg, name, "dynamics").model,
                "rms": dict(zip(AXES, np.sqrt(np.mean(residual**2, axis=0)).tolist())),
                "max": dict(zip(AXES, np.max(np.abs(residual), axis=0).tolist())),
                "prediction_rms_m": {f"{T:g}": prediction_error(model, t, states, extra, T) for T in intervals},
            }
        )
    return rows


def markdown(rows: list[dict]) -> str:
    """The model-error table in Markdown (um/s^2 and mm)."""
    intervals = list(rows[0]["prediction_rms_m"]) if rows else []
    header = (
        ["case", "filter (model)"]
        + [f"RMS a_{a} [um/s^2]" for a in AXES]
        + [f"max a_{a} [um/s^2]" for a in AXES]
        + [f"RMS {T} s prediction [mm]" for T in intervals]
    )
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for r in rows:
        cells = [r["case"], f"{r['filter']} ({r['model']})"]
        cells += [f"{UM * r['rms'][a]:.2f}" for a in AXES] + [f"{UM * r['max'][a]:.2f}" for a in AXES]
        cells += [f"{MM * r['prediction_rms_m'][T]:.3g}" for T in intervals]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def sweep_extra(truths: list[tuple[str, dict]]) -> tuple[list[dict], str]:
    """The model-error rows of a sweep's distinct truths, and their Markdown table (bench_eval.study hook)."""
    rows = [row for label, cfg in truths for row in model_error_rows(label, cfg)]
    return rows, markdown(rows)
