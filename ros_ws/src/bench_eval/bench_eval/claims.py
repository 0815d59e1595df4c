"""A paper's claims, tested against the bench's scores: the verdicts that open the report.

Each study lists its claims in its ``paper.yaml`` (``claims:``), each naming the score that decides it and a
rule; nothing here knows a study. A score is named by a dotted path into a filter's score block
(``rmse_converged_m``, ``mae.x``); its per-run values, when the metric family gives them, by ``runs``
(``mae_runs.x``), from which the Monte Carlo standard error and paired comparisons are computed.

A verdict never says more than the runs decide. Every rule is a two-sided test at the claim's ``level``
(default 5 %), and its verdict is one of
- "holds (TEST, n runs)": the runs decide the claim at that level;
- "does not hold (TEST, n runs)": the runs decide against it at that level;
- "undecided (n runs; ~N needed: TEST, 80 % power)": neither; N is the number of runs at which a true effect of
  the observed size would be decided with 80 % power (:func:`runs_needed`), or the reason no estimate exists
  (a single run gives no standard error, no paired difference).

Rules
- ``close_to``: the bench's value is within ``tolerance`` (relative, the paper's "about") of the paper's
  ``values[filter]``. Holds when the (1 - level) confidence interval of the bench's value (its per-run
  standard error, Student t) lies inside the band target ± tolerance·|target|; does not hold when it lies
  wholly outside.
- ``at_most``: the bench's value is at most ``values[filter]``: holds when the confidence interval lies at or
  below it, does not hold when it lies above.
- ``ordering``: ``order`` lists filters from best (smallest) to worst. Every consecutive pair is compared by a
  paired t-test over the same runs (seeds): holds when every step is significant in the claimed direction,
  does not hold when one is significant the other way.
- ``fraction_of_runs``: the per-run booleans ``runs`` are true in at least ``values[filter]`` of the runs:
  decided by the Clopper-Pearson interval of the observed rate (holds when it lies at or above the fraction,
  does not hold when below). A fraction of 1 can only be refuted: no finite number of runs shows a rate of 100 %.
Runs needed (t rules): the smallest N with sqrt(N) |d| / s >= t_{1-level/2, N-1} + t_{power, N-1}, where d is
the observed effect (mean paired difference, or the distance from the bench's value to the nearest edge of the
claimed band) and s the standard deviation over runs; for large N this is N = ((z_{1-level/2} + z_{power}) s /
d)^2. Runs needed (fraction): the smallest N at which the observed rate's interval would exclude the fraction.
A filter whose NEES is astronomically large (> 1e6 per degree of freedom) is reported as diverged, and fails
its claims.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import special

from bench_engine.config import ScenarioError, Section, lookup

RULES = ("close_to", "at_most", "ordering", "fraction_of_runs")
DIVERGED_NEES = 1e6
POWER = 0.8
"""Power at which the runs needed to decide an undecided claim are estimated."""
MAX_RUNS = 100_000
"""Runs-needed estimates beyond this are reported as "> MAX_RUNS"."""


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
    level: float = 0.05
    """Significance level of the claim's test (two-sided)."""


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
            if rule == "fraction_of_runs" and not 0.0 < v <= 1.0:
                raise ScenarioError(f"'{path}[{i}].values.{name}' must be a fraction in (0, 1], got {v!r}")
        order = tuple(sec.get("order", list, [] if rule != "ordering" else ...))
        if rule == "ordering" and len(order) < 2:
            raise ScenarioError(f"'{path}[{i}].order' must list at least two filters")
        level = sec.positive("level", 0.05)
        if level >= 0.5:
            raise ScenarioError(f"'{path}[{i}].level' must be below 0.5, got {level!r}")
        claim = Claim(
            cid,
            sec.get("claim", str),
            str(sec.get("paper", (str, int, float))),
            rule,
            sec.get("metric", str, ... if needs_metric else None),
            sec.get("runs", str, ... if rule == "fraction_of_runs" else None),
            sec.get("unit", str, ""),
            {str(k): float(v) for k, v in values.items()},
            order,
            sec.positive("tolerance", 0.1),
            level,
        )
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


@dataclass(frozen=True)
class Decision:
    """What the runs decide about one claim (or one filter's part of it)."""

    state: str
    """"holds", "fails" or "undecided"."""
    runs: int
    needed: int | None = None
    """Undecided: the runs needed to decide it (:func:`runs_needed`); None when there is no estimate."""
    why: str = ""
    """Undecided without an estimate: the reason (e.g. a single run has no standard error)."""


def runs_needed(effect: float, sd: float, level: float, power: float = POWER) -> int | None:
    """Runs at which a true effect ``effect`` with per-run standard deviation ``sd`` is decided by a two-sided
    t-test at ``level`` with probability ``power``: the smallest N >= 2 with
    sqrt(N) |effect| / sd >= t_{1-level/2, N-1} + t_{power, N-1} (for large N: N = ((z_{1-level/2} + z_power)
    sd / effect)^2). None when the effect is zero; MAX_RUNS + 1 when more than MAX_RUNS are needed."""
    if effect == 0.0 or not np.isfinite(effect) or not np.isfinite(sd):
        return None
    z = (special.ndtri(1.0 - level / 2.0) + special.ndtri(power)) * sd / abs(effect)
    if z * z > MAX_RUNS:
        return MAX_RUNS + 1
    n = np.arange(max(2, int(z * z)), int(z * z) + 200)  # t quantiles exceed z's: N is at least z^2
    enough = np.sqrt(n) * abs(effect) / sd >= special.stdtrit(n - 1, 1.0 - level / 2.0) + special.stdtrit(n - 1, power)
    return int(n[np.argmax(enough)]) if enough.any() else int(n[-1])


def _per_run(values: Any) -> np.ndarray | None:
    """Per-run values as floats (missing runs dropped), or None when the block gives none."""
    if not isinstance(values, list) or not values:
        return None
    return np.asarray([v for v in values if v is not None], dtype=float)


def decide_interval(value: float, runs: np.ndarray, low: float, high: float, level: float) -> Decision:
    """Is ``value`` (whose per-run values are ``runs``) inside [low, high] (either may be infinite)? Decided by
    the (1 - level) Student t confidence interval value ± t s / sqrt(n): holds when it lies inside, fails when
    it lies wholly outside; undecided otherwise, with the runs at which the interval's half-width would be
    below the distance from the value to the band's nearest edge."""
    n = len(runs)
    if n < 2:
        return Decision("undecided", n, why="a standard error needs ≥ 2 runs")
    sd = float(np.std(runs, ddof=1))
    half = float(special.stdtrit(n - 1, 1.0 - level / 2.0)) * sd / np.sqrt(n)
    if low <= value - half and value + half <= high:
        return Decision("holds", n)
    if value + half < low or value - half > high:
        return Decision("fails", n)
    edge = min(abs(value - e) for e in (low, high) if np.isfinite(e))
    needed = runs_needed(edge, sd, level)
    return Decision("undecided", n, needed, "" if needed else "the value lies on the band's edge")


def decide_paired(better: np.ndarray, worse: np.ndarray, level: float) -> Decision:
    """Is ``better`` smaller than ``worse``, run by run (the same seeds)? A two-sided paired t-test at
    ``level``: holds when significant in the claimed direction, fails when significant the other way. The
    same difference in every run decides by its sign."""
    d = worse - better
    n = len(d)
    if n < 2:
        return Decision("undecided", n, why="a paired t-test needs ≥ 2 runs")
    sd = float(np.std(d, ddof=1))
    if sd == 0.0:
        if d[0] == 0.0:
            return Decision("undecided", n, why="no difference in any run")
        return Decision("holds" if d[0] > 0.0 else "fails", n)
    t = float(d.mean()) / (sd / np.sqrt(n))
    p = float(2.0 * special.stdtr(n - 1, -abs(t)))  # the two-sided p of a one-sample t-test on d
    if p < level:
        return Decision("holds" if d.mean() > 0.0 else "fails", n)
    needed = runs_needed(float(d.mean()), sd, level)
    return Decision("undecided", n, needed, "" if needed else "mean difference zero")


def decide_fraction(flags: Sequence[bool], fraction: float, level: float) -> Decision:
    """Are the flags true in at least ``fraction`` of the runs? The (1 - level) Clopper-Pearson interval of the
    observed rate: holds when it lies at or above ``fraction``, fails when it lies below; undecided otherwise,
    with the smallest number of runs at which the observed rate's interval would exclude ``fraction``."""
    n, k = len(flags), int(sum(bool(f) for f in flags))
    if n == 0:
        return Decision("undecided", 0, why="no runs")

    def interval(k: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        with np.errstate(invalid="ignore", divide="ignore"):
            low = np.where(k > 0, special.betaincinv(k, n - k + 1, level / 2.0), 0.0)
            high = np.where(k < n, special.betaincinv(k + 1, n - k, 1.0 - level / 2.0), 1.0)
        return low, high

    low, high = interval(np.array(k), np.array(n))
    if low >= fraction:
        return Decision("holds", n)
    if high < fraction:
        return Decision("fails", n)
    rate = k / n
    if rate == fraction:
        return Decision(
            "undecided",
            n,
            why="a rate of 100 % is never shown by finitely many runs"
            if fraction == 1.0
            else "the observed rate equals the fraction",
        )
    ns = np.arange(n + 1, MAX_RUNS + 1)
    low, high = interval(np.round(rate * ns), ns)
    decided = (low >= fraction) | (high < fraction)
    return Decision("undecided", n, int(ns[np.argmax(decided)]) if decided.any() else MAX_RUNS + 1)


def _pct(x: float) -> str:
    return f"{100.0 * x:g} %"


def _count(runs: int) -> str:
    return f"{runs} run{'s' if runs != 1 else ''}"


def decided_by(spec: Claim) -> str:
    """The test and level that decide a claim, as its verdict states them."""
    ci = f"{_pct(1.0 - spec.level)} CI"
    return {
        "close_to": f"{ci} vs ±{_pct(spec.tolerance)}",
        "at_most": f"{ci} vs the bound",
        "ordering": f"paired t-test, {_pct(spec.level)}",
        "fraction_of_runs": f"{_pct(1.0 - spec.level)} Clopper–Pearson",
    }[spec.rule]


def _undecided_note(decisions: Sequence[Decision], spec: Claim) -> str:
    """ "n runs; ~N needed: TEST, 80 % power" (the largest need), or "n runs; the reason" (the first reason). The
    fraction rule's need is at the observed rate, not at a power."""
    head = _count(max(d.runs for d in decisions))
    reasons = [d.why for d in decisions if d.needed is None]
    if reasons:
        return f"{head}; {reasons[0]}"
    needed = max(d.needed for d in decisions)
    need = f"> {MAX_RUNS}" if needed > MAX_RUNS else f"~{needed}"
    how = "at the observed rate" if spec.rule == "fraction_of_runs" else f"{_pct(POWER)} power"
    return f"{head}; {need} needed: {decided_by(spec)}, {how}"


def verdict_text(results: Sequence[tuple[str, Decision]], spec: Claim) -> str:
    """The verdict of a claim from each filter's decision."""
    if not results:
        return "not tested (no filter of the claim was run)"
    tested = f"{decided_by(spec)}, {_count(max(d.runs for _, d in results))}"
    held = [n for n, d in results if d.state == "holds"]
    failed = [n for n, d in results if d.state == "fails"]
    open_ = [(n, d) for n, d in results if d.state == "undecided"]
    if len(held) == len(results):
        return f"holds ({tested})"
    if len(failed) == len(results):
        return f"does not hold ({tested})"
    if not open_:
        return f"holds only for {', '.join(held)} ({tested})"
    note = _undecided_note([d for _, d in open_], spec)
    if not held and not failed:
        return f"undecided ({note})"
    parts = ([f"holds for {', '.join(held)}"] if held else []) + (
        [f"does not hold for {', '.join(failed)}"] if failed else []
    )
    return f"{'; '.join(parts)}; undecided for {', '.join(n for n, _ in open_)} ({note})"


def _value(block: Mapping, spec: Claim) -> tuple[float | None, float]:
    """(bench value, its standard error) of the claim's score for one filter."""
    runs = lookup(block, spec.runs)
    value = lookup(block, spec.metric)
    se = mean_se(runs)[1] if isinstance(runs, list) and runs else float("nan")
    return (None if value is None else float(value)), se


def _band(spec: Claim, target: float) -> tuple[float, float]:
    if spec.rule == "close_to":
        return target - spec.tolerance * abs(target), target + spec.tolerance * abs(target)
    return -np.inf, target  # at_most


def _each_filter(
    scored: Mapping, spec: Claim, decide: Callable[[Mapping, float], tuple[str, Decision]]
) -> tuple[str, str]:
    """(bench text, verdict) of a claim decided filter by filter: a filter not run is named, one that diverged
    fails (no per-run figure of a filter that lost its target means anything), and ``decide(block, target)``
    gives each other one's text and decision."""
    results, texts = [], []
    for name, target in spec.values.items():
        block = scored.get(name)
        if block is None:
            texts.append(f"{name}: not run")
            continue
        if diverged(block):
            texts.append(f"{name}: diverged")
            results.append((name, Decision("fails", int(block.get("runs") or 1))))
            continue
        text, decision = decide(block, target)
        texts.append(f"{name}: {text}")
        results.append((name, decision))
    return "; ".join(texts), verdict_text(results, spec)


def _per_filter(scored: Mapping, spec: Claim) -> tuple[str, str]:
    def decide(block: Mapping, target: float) -> tuple[str, Decision]:
        value, se = _value(block, spec)
        text, runs = figure(value, se, spec.unit), int(block.get("runs") or 1)
        if value is None or not np.isfinite(value):
            return text, Decision("undecided", runs, why="no bench value")
        per_run = _per_run(lookup(block, spec.runs))
        if per_run is None:
            return text, Decision("undecided", runs, why="no per-run values: no standard error")
        return text, decide_interval(value, per_run, *_band(spec, target), spec.level)

    return _each_filter(scored, spec, decide)


def _paired_runs(a: Any, b: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """Two filters' per-run values over the same runs, runs missing in either dropped (None if not paired)."""
    if not isinstance(a, list) or not isinstance(b, list) or len(a) != len(b):
        return None
    keep = [(x, y) for x, y in zip(a, b) if x is not None and y is not None]
    return np.asarray([x for x, _ in keep], dtype=float), np.asarray([y for _, y in keep], dtype=float)


def _ordering(scored: Mapping, spec: Claim) -> tuple[str, str]:
    order = [n for n in spec.order if n in scored]
    if len(order) < 2:
        return "—", "not tested (fewer than two of the filters were run)"
    values = {n: "diverged" if diverged(scored[n]) else figure(*_value(scored[n], spec), spec.unit) for n in order}
    text = "; ".join(f"{n}: {values[n]}" for n in order)  # in the claimed order
    steps = []
    for better, worse in zip(order, order[1:]):
        step, runs = f"{better} < {worse}", int(scored[better].get("runs") or 1)
        lost = diverged(scored[better]), diverged(scored[worse])
        pair = _paired_runs(lookup(scored[better], spec.runs), lookup(scored[worse], spec.runs))
        if any(lost):  # a filter that lost its target is worse than one that did not
            decision = (
                Decision("undecided", runs, why="both diverged")
                if all(lost)
                else Decision("fails" if lost[0] else "holds", runs)
            )
        elif pair is None:
            decision = Decision("undecided", runs, why="no paired per-run values")
        else:
            decision = decide_paired(*pair, spec.level)
        steps.append((step, decision))
    if any(d.state == "fails" for _, d in steps):
        against = ", ".join(
            f"{worse} < {better}" for (better, worse), (_, d) in zip(zip(order, order[1:]), steps) if d.state == "fails"
        )
        return text, f"does not hold ({decided_by(spec)}, {_count(max(d.runs for _, d in steps))}: {against})"
    if all(d.state == "holds" for _, d in steps):
        return text, verdict_text(steps, spec)
    return text, f"undecided ({_undecided_note([d for _, d in steps if d.state == 'undecided'], spec)})"


def _fraction(scored: Mapping, spec: Claim) -> tuple[str, str]:
    def decide(block: Mapping, target: float) -> tuple[str, Decision]:
        flags = lookup(block, spec.runs) or []
        return f"{sum(bool(f) for f in flags)}/{len(flags)} runs", decide_fraction(flags, target, spec.level)

    return _each_filter(scored, spec, decide)


def evaluate(study: str, scored: Mapping, claims: Sequence[Claim], section: str) -> list[ClaimRow]:
    """One row per claim of a study, from its filters' score blocks ``scored`` ({filter: block})."""
    rows = []
    for spec in claims:
        rule = spec.rule
        if rule in ("close_to", "at_most"):
            bench, verdict = _per_filter(scored, spec)
        elif rule == "ordering":
            bench, verdict = _ordering(scored, spec)
        elif rule == "fraction_of_runs":
            bench, verdict = _fraction(scored, spec)
        else:
            raise ValueError(f"claim {spec.id!r}: rule must be one of {RULES}, got {rule!r}")
        rows.append(ClaimRow(study, spec.claim, spec.paper, bench, verdict, section))
    return rows
