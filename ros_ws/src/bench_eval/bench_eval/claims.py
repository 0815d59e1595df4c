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
  claimed direction, "does not hold" when one is significant the other way, else "not significant". With a
  single run the values alone decide, and the verdict says that no significance test was possible.
- ``fraction_of_runs``: the per-run booleans ``runs`` are true in at least ``values[filter]`` of the runs.
A filter whose NEES is astronomically large (> 1e6 per degree of freedom) is reported as diverged.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np
from scipy.special import stdtrit  # Student t quantile: t.ppf(q, df) = stdtrit(df, q)

from bench_engine.config import ScenarioError, Section

RULES = ("close_to", "at_most", "ordering", "fraction_of_runs")
DIVERGED_NEES = 1e6


@dataclass(frozen=True)
class Claim:
    """One claim of a paper.yaml, read strictly (:func:`read_claims`)."""

    id: str
    claim: str
    """The claim in words, as the report's table shows it."""
    paper: str
    """The paper's figure, as printed."""
    rule: str
    """One of RULES."""
    metric: str | None = None
    """Dotted path of the deciding score in a filter's block (not for fraction_of_runs)."""
    runs: str | None = None
    """Dotted path of its per-run values (standard errors, paired tests); the booleans for fraction_of_runs."""
    unit: str = ""
    values: Mapping[str, float] = field(default_factory=dict)
    """Filter -> the paper's figure (close_to, at_most) or the fraction of runs required (fraction_of_runs)."""
    order: tuple[str, ...] = ()
    """Filters from best (smallest score) to worst (ordering)."""
    tolerance: float = 0.1
    """Relative tolerance of close_to (the paper's "about")."""


def read_claims(data: Any, path: str = "claims") -> list[Claim]:
    """The ``claims`` list of a paper.yaml as Claims; ScenarioError naming the key on an unknown key, a missing
    key or a bad value."""
    if data is None:
        return []
    if not isinstance(data, list):
        raise ScenarioError(f"'{path}' must be a list of claims, got {type(data).__name__}")
    claims, ids = [], set()
    for i, entry in enumerate(data):
        sec = Section(entry, f"{path}[{i}]")
        cid = sec.get("id", str)
        if cid in ids:
            raise ScenarioError(f"'{path}[{i}].id': claim id '{cid}' is used twice")
        ids.add(cid)
        rule = sec.choice("rule", RULES)
        needs_metric = rule != "fraction_of_runs"
        values = sec.get("values", dict, {} if rule == "ordering" else ...)
        if rule == "ordering" and values:
            raise ScenarioError(f"'{path}[{i}].values': an ordering claim takes 'order', not values")
        for name, v in values.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ScenarioError(f"'{path}[{i}].values.{name}' must be a number, got {v!r}")
        order = tuple(sec.get("order", list, [] if rule != "ordering" else ...))
        if rule == "ordering" and len(order) < 2:
            raise ScenarioError(f"'{path}[{i}].order' must list at least two filters")
        claim = Claim(cid, sec.get("claim", str), str(sec.get("paper", (str, int, float))), rule,
                      sec.get("metric", str, ... if needs_metric else None),
                      sec.get("runs", str, ... if rule == "fraction_of_runs" else None),
                      sec.get("unit", str, ""), {str(k): float(v) for k, v in values.items()}, order,
                      sec.positive("tolerance", 0.1))
        sec.finish()
        claims.append(claim)
    return claims


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
    """A filter lost its target: its mean NEES is missing or beyond any chi-square band. A metric family that
    scores no NEES (e.g. residuals against a reference measurement) never reports divergence."""
    if "nees_mean" not in block:
        return False
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


def _value(block: Mapping, spec: Claim) -> tuple[float | None, float]:
    """(bench value, its standard error) of the claim's score for one filter."""
    runs = lookup(block, spec.runs)
    value = lookup(block, spec.metric)
    se = mean_se(runs)[1] if isinstance(runs, list) and runs else float("nan")
    return (None if value is None else float(value)), se


def _per_filter(scored: Mapping, spec: Claim, test) -> tuple[str, str]:
    results, texts = [], []
    for name, target in spec.values.items():
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
        texts.append(f"{name}: {figure(value, se, spec.unit)}")
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


def _ordering(scored: Mapping, spec: Claim) -> tuple[str, str]:
    order = [n for n in spec.order if n in scored]
    if len(order) < 2:
        return "—", "not tested (fewer than two of the filters were run)"
    if any(diverged(scored[n]) for n in order):
        return "; ".join(f"{n}: diverged" for n in order if diverged(scored[n])), "does not hold"
    values = {n: _value(scored[n], spec) for n in order}
    text = "; ".join(f"{n}: {figure(*values[n], spec.unit)}" for n in order)  # in the claimed order
    steps, untested = [], False
    for better, worse in zip(order, order[1:]):
        a, b = lookup(scored[better], spec.runs), lookup(scored[worse], spec.runs)
        if isinstance(a, list) and isinstance(b, list) and len(a) == len(b) > 1:
            d = np.asarray(b, dtype=float) - np.asarray(a, dtype=float)
            se = np.std(d, ddof=1) / np.sqrt(len(d))
            tcrit = stdtrit(len(d) - 1, 0.975)
            if se == 0.0:  # the same difference in every run: its sign decides
                steps.append(int(np.sign(d.mean())))
            else:
                steps.append(1 if d.mean() / se > tcrit else -1 if d.mean() / se < -tcrit else 0)
        else:  # a single run (or no per-run values): the values decide, with no significance test
            untested = True
            steps.append(0 if values[better][0] == values[worse][0] else 1 if values[better][0] < values[worse][0]
                         else -1)
    note = " (single run: no significance test)" if untested else ""
    if all(s == 1 for s in steps):
        return text, "holds" + note
    if any(s == -1 for s in steps):
        return text, "does not hold" + note
    return text, "not significant (paired t-test, 5 %)"


def _fraction(scored: Mapping, spec: Claim) -> tuple[str, str]:
    results, texts = [], []
    for name, target in spec.values.items():
        block = scored.get(name)
        if block is None:
            texts.append(f"{name}: not run")
            continue
        if diverged(block):  # a filter that lost the target: no per-run figure means anything
            texts.append(f"{name}: diverged")
            results.append((name, False))
            continue
        flags = lookup(block, spec.runs) or []
        met = sum(bool(f) for f in flags)
        texts.append(f"{name}: {met}/{len(flags)} runs")
        results.append((name, bool(flags) and met >= target * len(flags)))
    return "; ".join(texts), _combine(results)


def evaluate(study: str, scored: Mapping, claims: Sequence[Claim], section: str) -> list[ClaimRow]:
    """One row per claim of a study, from its filters' score blocks ``scored`` ({filter: block})."""
    rows = []
    for spec in claims:
        rule = spec.rule
        if rule == "close_to":
            bench, verdict = _per_filter(scored, spec, lambda v, se, t: _close_to(v, se, t, spec.tolerance))
        elif rule == "at_most":
            bench, verdict = _per_filter(scored, spec, _at_most)
        elif rule == "ordering":
            bench, verdict = _ordering(scored, spec)
        elif rule == "fraction_of_runs":
            bench, verdict = _fraction(scored, spec)
        else:
            raise ValueError(f"claim {spec.id!r}: rule must be one of {RULES}, got {rule!r}")
        rows.append(ClaimRow(study, spec.claim, spec.paper, bench, verdict, section))
    return rows
