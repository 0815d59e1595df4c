"""Sweeps (bench_eval.sweep: grids of the scenario's ``sweeps`` section through the graph, scripts/sweep.py) and
formation_cqkf's model errors (bench_studies.formation_cqkf.model_error)."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from graph_helpers import SCRIPTS, script

from bench_engine.batch import crosstalk
from bench_engine.config import ScenarioError, apply_overrides, load_scenario, scenario_path
from bench_eval import sweep
from bench_studies.formation_cqkf import model_error
from bench_studies.formation_cqkf.report import paired_ordering, paper004_case

COMPONENT_ROWS = ("δx [m]", "δy [m]", "δz [m]", "δvx [mm/s]", "δvy [mm/s]", "δvz [mm/s]")


def scenario_with(tmp_path: Path, grids: dict) -> Path:
    """formation_cqkf with its sweeps replaced by ``grids``, written as a YAML file."""
    cfg = yaml.safe_load(scenario_path("formation_cqkf").read_text())
    cfg["sweeps"] = grids
    path = tmp_path / "formation_cqkf.yaml"
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return path


# ---------------------------------------------------------------------------------- grid resolution


def test_tables_grid_resolves_placeholders_and_variant_order():
    grid = sweep.load_grid("formation_cqkf", "tables")
    assert len(grid.cells) == 16 and grid.columns == "rho"
    cell = next(
        c for c in grid.cells if c.labels == {"e": "0.005", "rho": "10km", "measurement": "linear", "interval": "10s"}
    )
    assert cell.variants == ["e0005", "size10km", "linear_10km", "interval10"]
    isl = cell.cfg["sensors"]["isl"]
    assert isl["type"] == "relative_position" and isl["sigma_position"] == 0.1 and isl["interval"] == 10.0
    assert cell.cfg["time"]["dt"] == 10.0 and cell.cfg["truth"]["chief"]["e"] == 0.005
    assert len(sweep.distinct_truths(grid)) == 4  # e x rho; measurement and interval keep the truth


def test_a_grids_own_set_reaches_every_cell_before_its_levels_and_the_command_line(tmp_path):
    grids = {
        "g": {
            "set": {"scoring.bounds": {}, "time.dt": 2.0},
            "axes": {"rho": {"1km": [], "10km": {"variants": ["size10km"], "set": {"time.dt": 5.0}}}},
        }
    }
    grid = sweep.load_grid(str(scenario_with(tmp_path, grids)), "g", ["time.duration=100"])
    one, ten = grid.cells
    assert one.cfg["scoring"]["bounds"] == {} == ten.cfg["scoring"]["bounds"]
    assert (one.cfg["time"]["dt"], ten.cfg["time"]["dt"]) == (2.0, 5.0)  # a level's set after the grid's
    assert "scoring.bounds={}" in one.overrides and one.overrides[-1] == "time.duration=100"
    assert load_scenario("formation_cqkf")["scoring"]["bounds"]  # the scenario itself keeps its bounds
    assert all(c.cfg["scoring"]["bounds"] == {} for c in sweep.load_grid("star_tracker", "tables").cells)


def test_numeric_axes_set_and_scale_the_keys_each_cell_has():
    noise = sweep.load_grid("formation_cqkf", "noise", ["time.duration=100"])
    base = load_scenario("formation_cqkf")["sensors"]["isl"]
    for cell in noise.cells:
        f = cell.values["noise_scale"]
        isl = cell.cfg["sensors"]["isl"]
        assert cell.cfg["time"]["duration"] == 100  # command-line overrides come last
        if cell.labels["measurement"] == "range_angles":
            assert np.isclose(isl["sigma_range"], f * base["sigma_range"])
            assert np.isclose(isl["sigma_azimuth"], f * base["sigma_azimuth"])
            assert "sigma_position" not in isl
        else:
            assert np.isclose(isl["sigma_position"], f * 0.0316227766)
    interval = sweep.load_grid("formation_cqkf", "interval")
    assert [c.cfg["time"]["dt"] for c in interval.cells[:10]] == list(range(1, 11))
    assert all(c.cfg["sensors"]["isl"]["interval"] == c.cfg["time"]["dt"] for c in interval.cells)


@pytest.mark.parametrize(
    "grids, grid, message",
    [
        ({"g": {"axes": {"rho": {"1km": [], "5km": ["size5km"]}}}}, "g", "unknown variant 'size5km'"),
        ({"g": {"axes": {"rho": {"1km": ["linear_{size}"]}}}}, "g", "unknown axis {size}"),
        ({"g": {"axes": {"s": {"values": [1.0, "big"], "set": ["time.dt"]}}}}, "g", "list of numbers"),
        ({"g": {"axes": {"s": {"values": [2.0], "scale": ["sensors.isl.sigma_rnage"]}}}}, "g", "sigma_rnage"),
        ({"g": {"axes": {"rho": {"1km": []}}, "columns": "size"}}, "g", "columns"),
        ({"g": {"axes": {"rho": {"1km": []}}}}, "nope", "unknown grid 'nope' .*available: g"),
    ],
)
def test_invalid_grids_fail_naming_the_value(tmp_path, grids, grid, message):
    with pytest.raises(ScenarioError, match=message.replace("{", "[{]").replace("}", "[}]")):
        sweep.load_grid(str(scenario_with(tmp_path, grids)), grid)


def test_invalid_cell_value_or_grid_fails_before_any_run(tmp_path):
    bad = {"bad": {"axes": {"sigma": {"values": [1.0e-5, -1.0], "set": ["filters.cw.dynamics.sigma_accel"]}}}}
    path = str(scenario_with(tmp_path, bad))
    out = tmp_path / "out"
    res = script("sweep.py", path, "--grid", "bad", "--out", str(out))
    assert res.returncode == 2
    assert "cell sigma--1" in res.stderr and "filters.cw.dynamics.sigma_accel" in res.stderr
    res = script("sweep.py", path, "--grid", "missing", "--out", str(out))
    assert res.returncode == 2
    assert "unknown grid 'missing'" in res.stderr
    assert not out.exists()


def test_each_paper_table_case_is_found_from_the_resolved_configuration():
    grid = sweep.load_grid("formation_cqkf", "tables")
    cases = {c.id: paper004_case(c.cfg) for c in grid.cells}
    found = {k: (v["table"], v["rho_m"]) for k, v in cases.items() if v}
    assert found == {
        "e-0__rho-1km__measurement-range_angles__interval-1s": (1, 1000.0),
        "e-0__rho-10km__measurement-range_angles__interval-1s": (1, 10000.0),
        "e-0.005__rho-1km__measurement-range_angles__interval-1s": (2, 1000.0),
        "e-0.005__rho-10km__measurement-range_angles__interval-1s": (2, 10000.0),
    }


def test_paired_ordering_marks_only_significant_differences():
    rng = np.random.default_rng(3)
    common = rng.normal(1.0, 0.3, 12)  # run-to-run spread shared by all filters (same measurements)
    runs = {"a": common, "b": common + 0.05 + rng.normal(0.0, 0.01, 12), "c": common + 0.06 + rng.normal(0.0, 0.2, 12)}
    assert paired_ordering(runs) in ("a < b ≈ c", "a < c ≈ b")
    assert paired_ordering({k: v[:1] for k, v in runs.items()}).count("≈") == 2  # one run: nothing is significant


# ---------------------------------------------------------------------------------- through the graph


def test_two_cell_sweep_runs_through_the_graph(tmp_path):
    grids = {"tiny": {"description": "two cells", "columns": "rho", "axes": {"rho": {"1km": [], "10km": ["size10km"]}}}}
    out = tmp_path / "sweep"
    cmd = [
        sys.executable,
        str(SCRIPTS / "sweep.py"),
        str(scenario_with(tmp_path, grids)),
        "--grid",
        "tiny",
        "--runs",
        "1",
        "--jobs",
        "2",
        "--out",
        str(out),
        "--set",
        "time.duration=60",
    ]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads((out / "sweep.json").read_text())
    assert [c["id"] for c in result["cells"]] == ["rho-1km", "rho-10km"]
    for cell in result["cells"]:
        assert (out / cell["id"] / "run_000" / "bag" / "metadata.yaml").is_file()
        assert cell["runs_ok"] == 1 and set(cell["score"]["estimators"]) == {"ss", "cw", "cwb"}
        assert cell["paper"]["table"] == 1  # e = 0, range/angles every 1 s
        mae = cell["score"]["estimators"]["ss"]["mae"]
        assert all(np.isfinite(v) and v > 0 for v in mae.values())
    # a 10x larger formation has a larger range noise and model error: larger errors
    big, small = (c["score"]["estimators"]["ss"]["mae"]["x"] for c in result["cells"][::-1])
    assert big > small
    table = (out / "table.md").read_text()
    header = "| state | rho=1km: ss (SS) | rho=1km: cw (CW) | rho=1km: cwb (CW+bias) | rho=10km: ss (SS) |"
    assert header in table
    for row in COMPONENT_ROWS:
        assert f"| {row} |" in table
    assert "(0.036)" in table and "(0.879)" in table  # paper Table 1 next to the bench
    assert "| rho=1km | ss (SS) | 1 | " in table and "| rho=10km | cwb (CW+bias) | 1 | " in table  # all cells
    assert "Model error against the nonlinear truth" in table
    assert (out / "errors_rho-1km.png").is_file()
    # the runs are kept: a second sweep into OUT refuses, --resume reuses them (same configs and seeds)
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    assert again.returncode == 2 and "already exists" in again.stderr
    resumed = subprocess.run(cmd + ["--resume"], capture_output=True, text=True, timeout=60)
    assert resumed.returncode == 0 and "(2 reused)" in resumed.stderr
    assert json.loads((out / "sweep.json").read_text())["cells"][1]["score"] == result["cells"][1]["score"]


def test_crosstalk_is_a_truth_message_count_other_than_the_steps(tmp_path):
    def bag(truth_count: int) -> Path:
        path = tmp_path / f"bag{truth_count}"
        path.mkdir()
        topics = [
            {"topic_metadata": {"name": name}, "message_count": n}
            for name, n in (("/clock", 61), ("/truth/state", truth_count), ("/ss/estimate", 61))
        ]
        (path / "metadata.yaml").write_text(
            yaml.safe_dump({"rosbag2_bagfile_information": {"topics_with_message_count": topics}})
        )
        return path

    assert not crosstalk(bag(61), 61)
    assert crosstalk(bag(262), 61)  # a second graph's truth on the same domain


# ---------------------------------------------------------------------------------------- model error


def test_model_error_is_zero_for_the_model_that_generated_the_truth():
    """With the exact CW truth the CW model leaves only the finite-difference error; SS's J2 terms show."""
    cfg = apply_overrides(load_scenario("formation_cqkf"), ["truth.model=hill_cw", "time.duration=600"])
    rows = {r["filter"]: r for r in model_error.model_error_rows("cw truth", cfg)}
    assert max(rows["cw"]["rms"].values()) < 1e-10
    assert rows["cw"]["prediction_rms_m"]["10"] < 1e-9
    assert rows["ss"]["rms"]["x"] > 3e-8  # SS's 2 n c vy vs CW's 2 n vy: 2 n (c - 1) |vy| ~ 1e-7 m/s^2
    j2 = {r["filter"]: r for r in model_error.model_error_rows("j2", load_scenario("formation_cqkf"))}
    assert j2["ss"]["rms"]["z"] < j2["cw"]["rms"]["z"]  # SS's cross-track frequency is the J2 one
    assert j2["cwb"]["rms"]["x"] < j2["cw"]["rms"]["x"]  # the best constant bias absorbs part of it
