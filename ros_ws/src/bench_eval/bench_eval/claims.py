"""A paper's claims, tested against the bench's scores: the verdicts that open the report.

Each study lists its claims in its ``paper.yaml`` (``claims:``), each naming the score that decides it and a
rule; nothing here knows a study. A score is named by a dotted path into a filter's score block
(``rmse_converged_m``, ``mae.x``); its per-run values, when the metric family gives them, by ``runs``
(``mae_runs.x``), from which the Monte Carlo standard error and paired comparisons are computed.

Rules
- ``close_to``: the bench's value is within ``tolerance`` (relative, the paper's "about") of the paper's
  ``values[filter]``, or within two standard errors of it.
- ``at_most``: the bench's value is at most ``values[filter]`` (plus two standard errors).
- ``ordering``: ``order`` lists filters from best (smallest) to worst; every consecutive pair is checked
  with a paired t-test at 5 % over the same runs (seeds). "holds" when every step is significant in the
  claimed direction, "does not hold" when one is significant the other way, else "not significant".
- ``fraction_of_runs``: the per-run booleans ``runs`` are true in at least ``values[filter]`` of the runs.
A filter whose NEES is astronomically large (> 1e6 per degree of freedom) is reported as diverged.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np
from scipy.stats import t as student

RULES = ("close_to", "at_most", "ordering", "fraction_of_runs")
DIVERGED_NEES = 1e6


@dataclass
class ClaimRow:
    study: str
    claim: str
    paper: str
    bench: str
    verdict: str
    section: str


def lookup(block: Mapping, path: str | None) -> Any:
    """The value at a dotted path of a score block (None when absent)."""
    if path is None:
        return None
    node: Any = block
    for part in path.split("."):
        if not isinstance(node, Mapping) or part not in node:
            return None
        node = node[part]
    return node


def diverged(block: Mapping) -> bool:
    nees, dof = block.get("nees_mean"), block.get("nees_dof") or len(block.get("mae") or {}) or 6
    return nees is None or not np.isfinite(nees) or nees > DIVERGED_NEES * dof


def mean_se(values: Sequence[float]) -> tuple[float, float]:
    """Mean and standard error of per-run values (NaN standard error for one run)."""
    v = np.asarray([x for x in values if x is not None], dtype=float)
    se = float(np.std(v, ddof=1) / np.sqrt(len(v))) if len(v) > 1 else float("nan")
    return float(np.mean(v)), se


def figure(value: float | None, se: float = float("nan"), unit: str = "") -> str:
    if value is None or not np.isfinite(value):
        return "—"
    text = f"{value:.3g} ± {se:.2g}" if np.isfinite(se) else f"{value:.3g}"
    return f"{text} {unit}".strip()


def _value(block: Mapping, spec: Mapping) -> tuple[float | None, float]:
    """(bench value, its standard error) of the claim's score for one filter."""
    runs = lookup(block, spec.get("runs"))
    value = lookup(block, spec["metric"])
    se = mean_se(runs)[1] if isinstance(runs, list) and runs else float("nan")
    return (None if value is None else float(value)), se


def _per_filter(scored: Mapping, spec: Mapping, test) -> tuple[str, str]:
    results, texts = [], []
    for name, target in spec["values"].items():
        block = scored.get(name)
        if block is None:
            texts.append(f"{name}: not run")
            continue
        if diverged(block):
            results.append((name, False))
            texts.append(f"{name}: diverged")
            continue
        value, se = _value(block, spec)
        ok = value is not None and test(value, se, float(target))
        results.append((name, ok))
        texts.append(f"{name}: {figure(value, se, spec.get('unit', ''))}")
    return "; ".join(texts), _combine(results)


def _combine(results: list[tuple[str, bool]]) -> str:
    held = [n for n, ok in results if ok]
    if not results:
        return "not tested (no filter of the claim was run)"
    if len(held) == len(results):
        return "holds"
    if not held:
        return "does not hold"
    return f"holds only for {', '.join(held)}"


def _close_to(value: float, se: float, target: float, tolerance: float) -> bool:
    return abs(value - target) <= max(tolerance * abs(target), 2.0 * se if np.isfinite(se) else 0.0)


def _at_most(value: float, se: float, target: float) -> bool:
    return value <= target + (2.0 * se if np.isfinite(se) else 0.0)


def _ordering(scored: Mapping, spec: Mapping) -> tuple[str, str]:
    order = [n for n in spec["order"] if n in scored]
    if len(order) < 2:
        return "—", "not tested (fewer than two of the filters were run)"
    if any(diverged(scored[n]) for n in order):
        return "; ".join(f"{n}: diverged" for n in order if diverged(scored[n])), "does not hold"
    values = {n: _value(scored[n], spec) for n in order}
    text = " < ".join(f"{n} {figure(*values[n], spec.get('unit', ''))}" for n in order)
    steps = []
    for better, worse in zip(order, order[1:]):
        a, b = lookup(scored[better], spec.get("runs")), lookup(scored[worse], spec.get("runs"))
        if isinstance(a, list) and isinstance(b, list) and len(a) == len(b) > 1:
            d = np.asarray(b, dtype=float) - np.asarray(a, dtype=float)
            se = np.std(d, ddof=1) / np.sqrt(len(d))
            tcrit = student.ppf(0.975, len(d) - 1)
            steps.append(1 if se > 0 and d.mean() / se > tcrit else -1 if se > 0 and d.mean() / se < -tcrit else 0)
        else:
            steps.append(0 if values[better][0] == values[worse][0] else 1 if values[better][0] < values[worse][0]
                         else -1)
    if all(s == 1 for s in steps):
        return text, "holds"
    if any(s == -1 for s in steps):
        return text, "does not hold"
    return text, "not significant (paired t-test, 5 %)"


def _fraction(scored: Mapping, spec: Mapping) -> tuple[str, str]:
    results, texts = [], []
    for name, target in spec["values"].items():
        block = scored.get(name)
        if block is None:
            continue
        flags = lookup(block, spec["runs"]) or []
        met = sum(bool(f) for f in flags)
        note = " (diverged)" if diverged(block) else ""
        texts.append(f"{name}: {met}/{len(flags)} runs{note}")
        results.append((name, bool(flags) and met >= float(target) * len(flags)))
    return "; ".join(texts), _combine(results)


def evaluate(study: str, scored: Mapping, claims: Sequence[Mapping], section: str) -> list[ClaimRow]:
    """One row per claim of a study, from its filters' score blocks ``scored`` ({filter: block})."""
    rows = []
    for spec in claims:
        rule = spec["rule"]
        if rule == "close_to":
            bench, verdict = _per_filter(scored, spec, lambda v, se, t: _close_to(v, se, t, spec.get("tolerance", 0.1)))
        elif rule == "at_most":
            bench, verdict = _per_filter(scored, spec, _at_most)
        elif rule == "ordering":
            bench, verdict = _ordering(scored, spec)
        elif rule == "fraction_of_runs":
            bench, verdict = _fraction(scored, spec)
        else:
            raise ValueError(f"claim {spec.get('id')!r}: rule must be one of {RULES}, got {rule!r}")
        rows.append(ClaimRow(study, spec["claim"], str(spec["paper"]), bench, verdict, section))
    return rows
