"""Claims (bench_eval.claims): a paper.yaml's claims read strictly, and verdicts computed from the scores."""
from __future__ import annotations

import re

import pytest

from bench_engine import plugins
from bench_engine.config import ScenarioError
from bench_eval.claims import Claim, diverged, evaluate, read_claims
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
    row, = evaluate("study", scored, [claim], "study")
    return row.bench, row.verdict


CLOSE = Claim("c", "about 100 m", "100 m", "close_to", "score", "score_runs", "m", {"a": 100.0, "b": 100.0}, (), 0.1)


def test_close_to_within_the_tolerance_or_two_standard_errors():
    assert verdict(CLOSE, {"a": block(105.0), "b": block(95.0)})[1] == "holds"
    assert verdict(CLOSE, {"a": block(105.0), "b": block(150.0)})[1] == "holds only for a"
    assert verdict(CLOSE, {"a": block(130.0), "b": block(150.0)})[1] == "does not hold"
    # 130 is 30 % off, but its runs scatter so much that 100 is within two standard errors
    bench, result = verdict(CLOSE, {"a": block(130.0, [40.0, 220.0, 130.0]), "b": block(100.0)})
    assert result == "holds" and bench.startswith("a: 130 ± 52 m")


def test_at_most_and_a_filter_that_was_not_run():
    claim = Claim("t", "within 33 s", "33 s", "at_most", "score", None, "s", {"a": 33.0, "b": 33.0})
    assert verdict(claim, {"a": block(30.0), "b": block(33.0)})[1] == "holds"
    bench, result = verdict(claim, {"a": block(34.0)})
    assert result == "does not hold" and "b: not run" in bench
    assert verdict(claim, {})[1].startswith("not tested")


def test_a_diverged_filter_is_said_diverged_and_fails_its_claim():
    assert diverged(block(1.0, nees=1.29e39)) and not diverged(block(1.0, nees=40.0))
    bench, result = verdict(CLOSE, {"a": block(100.0), "b": block(100.0, nees=1.29e39)})
    assert result == "holds only for a" and "b: diverged" in bench and "e+39" not in bench
    frac = Claim("f", "below after 80 s", "< 0.5 m", "fraction_of_runs", None, "ok_runs", "", {"pf": 1.0, "sir": 1.0})
    bench, result = verdict(frac, {"pf": {"nees_mean": 6.0, "ok_runs": [True, True]},
                                   "sir": {"nees_mean": float("inf"), "ok_runs": [False, False]}})
    assert result == "holds only for pf" and bench == "pf: 2/2 runs; sir: diverged"
    frac_half = Claim("f", "", "", "fraction_of_runs", None, "ok_runs", "", {"pf": 0.5})
    assert verdict(frac_half, {"pf": {"nees_mean": 6.0, "ok_runs": [True, False]}})[1] == "holds"
    assert verdict(frac, {"pf": {"nees_mean": 6.0, "ok_runs": [True, False]}})[1] == "does not hold"


def test_ordering_is_decided_by_a_paired_test_over_the_same_runs():
    claim = Claim("o", "a < b < c", "", "ordering", "score", "score_runs", "m", {}, ("a", "b", "c"))
    base = [1.0, 2.0, 3.0, 4.0, 5.0]
    scored = {n: block(sum(r) / 5, r) for n, r in
              (("a", base), ("b", [x + 0.5 for x in base]), ("c", [x + 1.0 + 0.01 * i for i, x in enumerate(base)]))}
    assert verdict(claim, scored)[1] == "holds"
    # reversed: b better than a in every run
    scored["b"] = block(2.5, [x - 0.5 for x in base])
    assert verdict(claim, scored)[1] == "does not hold"
    # a paired difference that is as often positive as negative is not significant
    scored["b"] = block(3.0, [x + d for x, d in zip(base, (0.3, -0.3, 0.2, -0.2, 0.01))])
    assert verdict(claim, scored)[1].startswith("not significant")
    assert verdict(claim, {"a": scored["a"]})[1].startswith("not tested")


@pytest.mark.parametrize("entry, message", [
    ({"id": "x", "claim": "c", "paper": "p", "rule": "roughly", "metric": "m", "values": {"a": 1}},
     "'claims[0].rule' must be one of"),
    ({"id": "x", "claim": "c", "paper": "p", "rule": "at_most", "metric": "m", "values": {"a": 1}, "tol": 0.1},
     "tol"),
    ({"id": "x", "claim": "c", "paper": "p", "rule": "at_most", "values": {"a": 1}}, "'claims[0].metric'"),
    ({"id": "x", "claim": "c", "paper": "p", "rule": "ordering", "metric": "m", "order": ["a"]},
     "'claims[0].order' must list at least two"),
    ({"id": "x", "claim": "c", "paper": "p", "rule": "close_to", "metric": "m", "values": {"a": "645 m"}},
     "'claims[0].values.a' must be a number"),
])
def test_a_bad_claim_is_refused_naming_its_key(entry, message):
    with pytest.raises(ScenarioError, match=re.escape(message)):
        read_claims([entry])


def test_every_registered_study_has_valid_claims_on_scores_its_metric_gives(tmp_path):
    for name in plugins.names("studies"):
        found = study(name)
        assert found.claims, f"{name} states no claim"
        assert len({c.id for c in found.claims}) == len(found.claims)
    bad = tmp_path / "paper.yaml"
    bad.write_text("paper: {}\nclaims: []\nclaimz: []\n")
    with pytest.raises(ScenarioError, match="claimz"):
        load_paper(bad)


def test_the_report_links_each_verdict_to_its_section_and_puts_no_raw_nees_in_a_diverged_section(tmp_path):
    mae = {a: 0.1 for a in ("x", "y", "z")} | {a: 0.001 for a in ("vx", "vy", "vz")}
    scored = {"formation_pf": {
        "pf": {"runs": 2, "mae": mae, "settling_time_s": 40.0, "nees_mean": 6.1, "nees_dof": 6,
               "nees_bounds": [5.0, 7.0], "below_after_runs": [True, True]},
        "sir": {"runs": 2, "mae": {a: 1e20 for a in mae}, "settling_time_s": None, "nees_mean": 1.29e39,
                "nees_dof": 6, "nees_bounds": [5.0, 7.0], "below_after_runs": [False, False]}}}
    text = write_report(tmp_path, scored, {}).read_text()
    row = next(line for line in text.splitlines() if line.startswith("| [formation_pf](#formation_pf)"))
    assert "pf: 2/2 runs; sir: diverged" in row and row.endswith("| **holds only for pf** |")
    assert "e+39" not in text and "1.29e39" not in text and "e+20" not in text
    assert text.index("## Claims") < text.index("## formation_pf")


def test_a_single_run_ordering_says_it_was_not_tested_for_significance():
    claim = Claim("o", "a < b", "", "ordering", "score", "score_runs", "m", {}, ("a", "b"))
    assert verdict(claim, {"a": block(1.0, [1.0]), "b": block(2.0, [2.0])})[1] == \
        "holds (single run: no significance test)"
    assert verdict(claim, {"a": block(3.0, [3.0]), "b": block(2.0, [2.0])})[1].startswith("does not hold (single")
