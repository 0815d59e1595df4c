"""Claims (bench_eval.claims): a paper.yaml's claims read strictly, and verdicts computed from the scores."""

from __future__ import annotations

import re

import numpy as np
import pytest
from scipy import stats

from bench_engine import plugins
from bench_engine.config import ScenarioError
from bench_eval.claims import Claim, diverged, evaluate, read_claims, runs_needed
from bench_eval.report import write_report
from bench_eval.study import load_paper, study


def block(value=None, runs=None, nees=5.0, **extra):
    out = {"runs": len(runs or [1]), "nees_mean": nees, "nees_dof": 6, **extra}
    if value is not None:
        out["score"] = value
    if runs is not None:
        out["score_runs"] = runs
    return out


def verdict(claim: Claim, scored: dict) -> tuple[str, str]:
    (row,) = evaluate("study", scored, [claim], "study")
    return row.bench, row.verdict


CLOSE = Claim("c", "about 100 m", "100 m", "close_to", "score", "score_runs", "m", {"a": 100.0, "b": 100.0}, (), 0.1)


def spread(mean, half_width=1.0, n=5):
    """n per-run values with the given mean, evenly spread over mean ± half_width."""
    return [mean + half_width * x for x in np.linspace(-1.0, 1.0, n)]


def test_close_to_holds_only_when_the_confidence_interval_lies_inside_the_band():
    a, b = spread(105.0), spread(95.0)  # SE 0.79: 95 % CI 105 ± 2.2 inside [90, 110]
    assert verdict(CLOSE, {"a": block(105.0, a), "b": block(95.0, b)})[1] == "holds (95 % CI vs ±10 %, 5 runs)"
    assert (
        verdict(CLOSE, {"a": block(105.0, a), "b": block(150.0, spread(150.0))})[1]
        == "holds only for a (95 % CI vs ±10 %, 5 runs)"
    )
    assert (
        verdict(CLOSE, {"a": block(130.0, spread(130.0)), "b": block(150.0, spread(150.0))})[1]
        == "does not hold (95 % CI vs ±10 %, 5 runs)"
    )
    # 130 is 30 % off, but its runs scatter so much that the interval reaches into the band: not decided
    bench, result = verdict(CLOSE, {"a": block(130.0, [40.0, 220.0, 130.0]), "b": block(100.0, spread(100.0))})
    assert bench.startswith("a: 130 ± 52 m")
    assert re.fullmatch(r"holds for b; undecided for a \(3 runs; ~(\d+) needed: 95 % CI vs ±10 %, 80 % power\)", result)
    assert int(re.search(r"~(\d+)", result).group(1)) > 3


def test_at_most_and_a_filter_that_was_not_run():
    claim = Claim("t", "within 33 s", "33 s", "at_most", "score", "score_runs", "s", {"a": 33.0, "b": 33.0})
    assert (
        verdict(claim, {"a": block(30.0, spread(30.0)), "b": block(28.0, spread(28.0))})[1]
        == "holds (95 % CI vs the bound, 5 runs)"
    )
    bench, result = verdict(claim, {"a": block(40.0, spread(40.0))})
    assert result == "does not hold (95 % CI vs the bound, 5 runs)" and "b: not run" in bench
    # exactly at the bound: the interval always straddles it, and no number of runs is estimated
    assert (
        verdict(claim, {"a": block(33.0, spread(33.0))})[1] == "undecided (5 runs; the value lies on the band's edge)"
    )
    assert verdict(claim, {})[1].startswith("not tested")


def test_a_score_without_per_run_values_or_with_a_single_run_is_undecided():
    """No standard error, no decision: whatever the value, a threshold claim is not decided."""
    no_runs = Claim("t", "within 33 s", "33 s", "at_most", "score", None, "s", {"a": 33.0})
    assert (
        verdict(no_runs, {"a": block(3.0) | {"runs": 10}})[1]
        == "undecided (10 runs; no per-run values: no standard error)"
    )
    assert (
        verdict(CLOSE, {"a": block(100.0, [100.0]), "b": block(500.0, [500.0])})[1]
        == "undecided (1 run; a standard error needs ≥ 2 runs)"
    )


def test_a_diverged_filter_is_said_diverged_and_fails_its_claim():
    assert diverged(block(1.0, nees=1.29e39)) and not diverged(block(1.0, nees=40.0))
    bench, result = verdict(CLOSE, {"a": block(100.0, spread(100.0)), "b": block(100.0, nees=1.29e39)})
    assert result == "holds only for a (95 % CI vs ±10 %, 5 runs)" and "b: diverged" in bench and "e+39" not in bench
    order = Claim("o", "a < b", "", "ordering", "score", "score_runs", "m", {}, ("a", "b"))
    assert verdict(order, {"a": block(1.0, [1.0]), "b": block(1.0, [1.0], nees=1.29e39)})[1].startswith("holds")
    assert verdict(order, {"a": block(1.0, [1.0], nees=1.29e39), "b": block(1.0, [1.0])})[1].startswith("does not hold")


FRACTION = Claim("f", "below after 80 s", "< 0.5 m", "fraction_of_runs", None, "ok_runs", "", {"pf": 0.9, "sir": 0.9})


def test_fraction_of_runs_is_decided_by_the_clopper_pearson_interval():
    def flags(passed, runs):
        return {"nees_mean": 6.0, "ok_runs": [True] * passed + [False] * (runs - passed)}

    # 36 of 36: the 95 % interval's lower end 0.025^(1/36) = 0.9026 reaches 0.9; 35 of 35 (0.8999) does not
    assert verdict(FRACTION, {"pf": flags(36, 36)})[1] == "holds (95 % Clopper–Pearson, 36 runs)"
    assert (
        verdict(FRACTION, {"pf": flags(35, 35)})[1]
        == "undecided (35 runs; ~36 needed: 95 % Clopper–Pearson, at the observed rate)"
    )
    assert (
        verdict(FRACTION, {"pf": flags(36, 36), "sir": flags(0, 2)})[1]
        == "holds only for pf (95 % Clopper–Pearson, 36 runs)"
    )
    # one failure in one run decides nothing against 90 %, but refutes "every run" at once
    assert verdict(FRACTION, {"sir": flags(0, 1)})[1].startswith("undecided (1 run; ~2 needed")
    every = Claim("f", "", "", "fraction_of_runs", None, "ok_runs", "", {"pf": 1.0})
    assert verdict(every, {"pf": flags(0, 1)})[1] == "does not hold (95 % Clopper–Pearson, 1 run)"
    assert (
        verdict(every, {"pf": flags(50, 50)})[1]
        == "undecided (50 runs; a rate of 100 % is never shown by finitely many runs)"
    )
    bench, result = verdict(FRACTION, {"pf": flags(36, 36), "sir": {"nees_mean": float("inf"), "ok_runs": [False]}})
    assert result.startswith("holds only for pf") and bench == "pf: 36/36 runs; sir: diverged"


ORDER = Claim("o", "a < b < c", "", "ordering", "score", "score_runs", "m", {}, ("a", "b", "c"))


def ordered(a, b, c):
    return {n: block(float(np.mean(r)), list(map(float, r))) for n, r in (("a", a), ("b", b), ("c", c))}


def test_ordering_is_decided_by_a_paired_test_over_the_same_runs():
    base = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    steps = np.array([0.0, 0.01, -0.01, 0.02, -0.02])
    # a clear paired difference: holds, although the runs' spread (1.6) hides it in the unpaired means
    scored = ordered(base, base + 0.5 + steps, base + 1.0 + steps)
    assert verdict(ORDER, scored)[1] == "holds (paired t-test, 5 %, 5 runs)"
    # the opposite: b better than a in every run
    assert (
        verdict(ORDER, ordered(base, base - 0.5 + steps, base + 1.0))[1]
        == "does not hold (paired t-test, 5 %, 5 runs: b < a)"
    )
    # a paired difference as often positive as negative: undecided, with the runs a real effect of that size needs
    bench, result = verdict(ORDER, ordered(base, base + np.array([0.3, -0.1, 0.25, -0.2, 0.1]), base + 1.0))
    assert re.fullmatch(r"undecided \(5 runs; ~\d+ needed: paired t-test, 5 %, 80 % power\)", result)
    assert 5 < int(re.search(r"~(\d+)", result).group(1)) < 200
    assert verdict(ORDER, {"a": scored["a"]})[1].startswith("not tested")


def test_a_single_run_never_decides_an_ordering():
    claim = Claim("o", "a < b", "", "ordering", "score", "score_runs", "m", {}, ("a", "b"))
    for a, b in ((1.0, 2.0), (3.0, 2.0), (1.0, 100.0)):
        assert (
            verdict(claim, {"a": block(a, [a]), "b": block(b, [b])})[1]
            == "undecided (1 run; a paired t-test needs ≥ 2 runs)"
        )
    # runs that cannot be paired (different counts) decide nothing either
    assert (
        verdict(claim, {"a": block(1.0, [1.0, 1.1]), "b": block(2.0, [2.0, 2.1, 2.2])})[1]
        == "undecided (2 runs; no paired per-run values)"
    )
    # the same difference in every run decides by its sign
    assert (
        verdict(claim, {"a": block(1.0, [1.0, 2.0]), "b": block(2.0, [1.5, 2.5])})[1]
        == "holds (paired t-test, 5 %, 2 runs)"
    )


def test_the_claims_own_level_decides_and_is_stated():
    strict = Claim("o", "a < b", "", "ordering", "score", "score_runs", "m", {}, ("a", "b"), level=0.001)
    loose = Claim("o", "a < b", "", "ordering", "score", "score_runs", "m", {}, ("a", "b"), level=0.05)
    rng = np.random.default_rng(7)
    a = rng.normal(0.0, 1.0, 8)
    b = a + 1.0 + rng.normal(0.0, 1.0, 8)  # p ~ 0.01: significant at 5 %, not at 0.1 %
    scored = {"a": block(float(a.mean()), list(a)), "b": block(float(b.mean()), list(b))}
    assert verdict(loose, scored)[1] == "holds (paired t-test, 5 %, 8 runs)"
    assert (
        verdict(strict, scored)[1].startswith("undecided (8 runs; ~")
        and "paired t-test, 0.1 %" in verdict(strict, scored)[1]
    )


def test_no_rule_says_holds_more_often_than_its_level_when_nothing_is_there():
    """Null data (no true difference, the bench's value exactly at the band's edge): over 200 synthetic
    10-run Monte Carlos, "holds" comes out at most about level/2 of the time (a two-sided test's one tail)."""
    rng = np.random.default_rng(11)
    order = Claim("o", "a < b", "", "ordering", "score", "score_runs", "m", {}, ("a", "b"))
    at_most = Claim("t", "at most 10", "", "at_most", "score", "score_runs", "m", {"a": 10.0})
    held = {"ordering": 0, "at_most": 0}
    for _ in range(200):
        a, b = rng.normal(5.0, 1.0, 10), rng.normal(5.0, 1.0, 10)
        held["ordering"] += verdict(order, {"a": block(a.mean(), list(a)), "b": block(b.mean(), list(b))})[
            1
        ].startswith("holds")
        x = rng.normal(10.0, 1.0, 10)
        held["at_most"] += verdict(at_most, {"a": block(x.mean(), list(x))})[1].startswith("holds")
    assert held["ordering"] <= 0.025 * 200 * 2 and held["at_most"] <= 0.025 * 200 * 2, held


def test_runs_needed_gives_the_stated_power():
    """With the estimated number of runs, a true effect of the observed size is decided in about 80 % of
    Monte Carlos (2000 simulated paired experiments)."""
    for effect, sd in ((0.5, 1.0), (0.2, 1.0), (2.0, 1.0)):
        n = runs_needed(effect, sd, 0.05)
        d = np.random.default_rng(3).normal(effect, sd, (2000, n))
        power = np.mean(stats.ttest_1samp(d, 0.0, axis=1).pvalue < 0.05)
        assert power >= 0.77, (effect, n, power)
        assert n == 2 or np.mean(stats.ttest_1samp(d[:, : n - 1], 0.0, axis=1).pvalue < 0.05) < 0.82, (effect, n)
    assert runs_needed(0.0, 1.0, 0.05) is None
    # the z form for large N
    assert abs(runs_needed(0.05, 1.0, 0.05) - ((1.959964 + 0.841621) / 0.05) ** 2) < 5


@pytest.mark.parametrize(
    "entry, message",
    [
        (
            {"id": "x", "claim": "c", "paper": "p", "rule": "roughly", "metric": "m", "values": {"a": 1}},
            "'claims[0].rule' must be one of",
        ),
        (
            {"id": "x", "claim": "c", "paper": "p", "rule": "at_most", "metric": "m", "values": {"a": 1}, "tol": 0.1},
            "tol",
        ),
        ({"id": "x", "claim": "c", "paper": "p", "rule": "at_most", "values": {"a": 1}}, "'claims[0].metric'"),
        (
            {"id": "x", "claim": "c", "paper": "p", "rule": "ordering", "metric": "m", "order": ["a"]},
            "'claims[0].order' must list at least two",
        ),
        (
            {"id": "x", "claim": "c", "paper": "p", "rule": "close_to", "metric": "m", "values": {"a": "645 m"}},
            "'claims[0].values.a' must be a number",
        ),
        (
            {"id": "x", "claim": "c", "paper": "p", "rule": "fraction_of_runs", "runs": "r", "values": {"a": 1.5}},
            "'claims[0].values.a' must be a fraction in (0, 1]",
        ),
        (
            {"id": "x", "claim": "c", "paper": "p", "rule": "at_most", "metric": "m", "values": {"a": 1}, "level": 0.5},
            "'claims[0].level' must be below 0.5",
        ),
    ],
)
def test_a_bad_claim_is_refused_naming_its_key(entry, message):
    with pytest.raises(ScenarioError, match=re.escape(message)):
        read_claims([entry])


def test_every_registered_study_has_valid_claims_on_scores_its_metric_gives(tmp_path):
    for name in plugins.names("studies"):
        found = study(name)
        assert found.claims, f"{name} states no claim"
        assert len({c.id for c in found.claims}) == len(found.claims)
        assert isinstance(found.demo_runs, int) and found.demo_runs >= 1, name  # make demo's seeds of the study
    bad = tmp_path / "paper.yaml"
    bad.write_text("paper: {}\nclaims: []\nclaimz: []\n")
    with pytest.raises(ScenarioError, match="claimz"):
        load_paper(bad)


def test_the_report_links_each_verdict_to_its_section_and_puts_no_raw_nees_in_a_diverged_section(tmp_path):
    mae = {a: 0.1 for a in ("x", "y", "z")} | {a: 0.001 for a in ("vx", "vy", "vz")}
    scored = {
        "formation_pf": {
            "pf": {
                "runs": 2,
                "mae": mae,
                "settling_time_s": 40.0,
                "nees_mean": 6.1,
                "nees_dof": 6,
                "nees_bounds": [5.0, 7.0],
                "below_after_runs": [True, True],
            },
            "sir": {
                "runs": 2,
                "mae": {a: 1e20 for a in mae},
                "settling_time_s": None,
                "nees_mean": 1.29e39,
                "nees_dof": 6,
                "nees_bounds": [5.0, 7.0],
                "below_after_runs": [False, False],
            },
        }
    }
    text = write_report(tmp_path, scored, {}).read_text()
    row = next(line for line in text.splitlines() if line.startswith("| [formation_pf](#formation_pf)"))
    assert "pf: 2/2 runs; sir: diverged" in row and row.endswith(
        "| **does not hold for sir; undecided for pf (2 runs; ~36 needed: 95 % Clopper–Pearson, at the observed "
        "rate)** |"
    )
    assert "e+39" not in text and "1.29e39" not in text and "e+20" not in text
    assert text.index("## Claims") < text.index("## formation_pf")
