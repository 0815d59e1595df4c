"""One word for one thing: an *estimator* is any node that publishes estimates, selected by ``--estimators`` or
the scenario's ``estimators`` whatever its kind (filter, tracker, smoother, star tracker). The old words still
work, each with a one-line notice: ``--filters``, the scenario key ``default_filters``, and bags recorded before
the change (their run_config.yaml says ``filters``) still score and replay."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from graph_helpers import script

from bench_engine import settings
from bench_engine.config import ScenarioError, apply_overrides, load_scenario
from bench_engine.graph import build_graph, resolve_estimators
from bench_engine.launcher import validate
from bench_engine.scenario import check_top_level, upgrade_run_config
from bench_eval.scoring import load_bag, score_bags

DATA = Path(__file__).parent / "data"
FORMATION = str(DATA / "tracker_formation.yaml")


@pytest.fixture(autouse=True)
def fresh_notices():
    settings._NOTICES.clear()  # each notice is printed once per process
    yield
    settings._NOTICES.clear()


def estimator_kinds(cfg: dict, selected: list[str] | None) -> dict[str, str]:
    return {n.name: n.kind for n in build_graph(cfg, selected, record=False).of_role("estimator")}


def test_every_estimator_kind_is_selected_by_name_trackers_and_smoothers_included() -> None:
    cfg = load_scenario(FORMATION)
    assert estimator_kinds(cfg, None) == {"cw": "filter", "gnn": "tracker"}  # the scenario's estimators
    assert estimator_kinds(cfg, ["gnn"]) == {"gnn": "tracker"}  # a tracker alone
    assert estimator_kinds(cfg, ["cw"]) == {"cw": "filter"}  # no tracker unless selected
    grace = load_scenario("grace_velocity")
    assert estimator_kinds(grace, ["kf_a", "kf_a_lag"]) == {"kf_a": "filter", "kf_a_lag": "fixed_lag"}
    assert estimator_kinds(grace, ["kf_b"]) == {"kf_b": "filter"}
    with pytest.raises(ScenarioError, match="consumes /kf_a/estimate.*select estimator 'kf_a' too"):
        build_graph(grace, ["kf_a_lag"], record=False)


def test_a_scenario_with_default_filters_still_loads_with_one_notice(tmp_path: Path, capsys) -> None:
    old = tmp_path / "old.yaml"
    text = (DATA / "tracker_formation.yaml").read_text().replace("estimators: [cw, gnn]", "default_filters: [cw]")
    old.write_text(text)
    cfg = load_scenario(str(old))
    check_top_level(cfg)
    assert resolve_estimators(cfg, None) == ["cw"]
    validate(cfg, ["cw"], "truth")
    err = capsys.readouterr().err
    assert err.count("notice:") == 1
    assert "the scenario key 'default_filters' is deprecated: call it 'estimators'" in err
    with pytest.raises(ScenarioError, match="'default_filters' and 'estimators' are one setting"):
        check_top_level(apply_overrides(cfg, ["estimators=[cw]"]))


def _old_form(run_dir: Path) -> None:
    """Rewrite a run's configuration as bags recorded before the change have it."""
    for path in (run_dir / "run_config.yaml", run_dir / "bag" / "run_config.yaml"):
        run = yaml.safe_load(path.read_text())
        run = {("filters" if k == "estimators" else k): v for k, v in run.items()}
        run["scenario"] = {("default_filters" if k == "estimators" else k): v for k, v in run["scenario"].items()}
        path.write_text(yaml.safe_dump(run, sort_keys=False))


def test_filters_still_runs_and_a_bag_of_the_old_form_scores_and_replays(tmp_path: Path) -> None:
    run = tmp_path / "run"
    res = script(
        "launch.py",
        "leo_radar",
        "--filters",
        "ukf",
        "--set",
        "time.duration=20",
        "--out",
        str(run),
        "--single-process",
        "--json",
        timeout=240,
    )
    assert res.returncode == 0, res.stderr[-2000:]
    assert "notice: --filters is deprecated: use --estimators" in res.stderr
    assert yaml.safe_load((run / "run_config.yaml").read_text())["estimators"] == ["ukf"]
    new = json.loads(res.stdout)
    assert set(new["estimators"]) == {"ukf"}

    _old_form(run)
    assert "filters" in yaml.safe_load((run / "bag" / "run_config.yaml").read_text())
    assert load_bag(run / "bag").run["estimators"] == ["ukf"]
    assert score_bags([run / "bag"])["estimators"]["ukf"] == new["estimators"]["ukf"]
    assert upgrade_run_config({"filters": ["a"], "scenario": {}}) == {"estimators": ["a"], "scenario": {}}

    replay = tmp_path / "replay"
    res = script("replay.py", str(run / "bag"), "--estimators", "ekf", "--out", str(replay), "--json", timeout=240)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "'default_filters' is deprecated" in res.stderr
    assert set(json.loads(res.stdout)["estimators"]) == {"ekf"}
    replayed = yaml.safe_load((replay / "run_config.yaml").read_text())
    assert replayed["estimators"] == ["ekf"] and "default_filters" not in replayed["scenario"]
