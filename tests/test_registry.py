"""Extension by registration: a package outside the bench registers a sensor type, an estimator, two pipeline
stages and a metric (tests/plugin_example), and they run through the real ROS 2 graph and the scorer with no
generic edit.

The package is "installed" the way importlib.metadata finds any package: a ``*.dist-info`` directory with
its entry points on PYTHONPATH. The launched nodes inherit PYTHONPATH, so every process sees the plugin.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from graph_helpers import read_bag, script

EXAMPLE = Path(__file__).resolve().parent / "plugin_example"


@pytest.fixture(scope="module")
def plugin_path(tmp_path_factory) -> str:
    site = tmp_path_factory.mktemp("site")
    shutil.copy(EXAMPLE / "bench_plugin_example.py", site)
    info = site / "bench_plugin_example-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: bench-plugin-example\nVersion: 0.1\n")
    shutil.copy(EXAMPLE / "entry_points.txt", info)
    return str(site)


def test_the_plugins_components_are_registered(plugin_path):
    code = (
        "from bench_engine import plugins\n"
        "print(plugins.names('sensors'), plugins.names('estimators'), plugins.names('node_kinds'))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        env={"PYTHONPATH": plugin_path, "PATH": ""},
    ).stdout
    assert "'range_only'" in out and "'inflated_ekf'" in out and "'relay'" in out and "'smoother'" in out


def test_a_plugins_angle_label_is_wrapped_like_the_bench_own(plugin_path):
    """The plugin registers ``bearing`` under tracking_bench.angle_labels: a state error over it is wrapped, and a
    measurement model's angles include it (bench_engine.labels)."""
    code = (
        "from bench_models.models import angle_components\n"
        "from bench_models.states import state_error\n"
        "print(angle_components(['range', 'bearing']), float(state_error(['bearing'], [3.0], [-3.0])[1][0]))"
    )
    env = {"PATH": ""}
    plain = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env).stdout
    plugged = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env={**env, "PYTHONPATH": plugin_path}
    ).stdout.split()
    assert plain.split() == ["()", "6.0"]
    assert plugged[0] == "(1,)" and float(plugged[1]) == pytest.approx(6.0 - 2 * np.pi, abs=1e-12)


@pytest.mark.parametrize("window", [0, 5])
def test_registered_sensor_estimator_and_three_stage_pipeline_run_through_the_graph(plugin_path, tmp_path, window):
    res = script(
        "launch.py",
        str(EXAMPLE / "plugin_demo.yaml"),
        "--out",
        str(tmp_path),
        "--json",
        "--set",
        f"time.pacing_window={window}",
        extra_env={"PYTHONPATH": plugin_path},
    )
    assert res.returncode == 0, res.stderr[-3000:]
    scored = json.loads(res.stdout)
    assert scored["metric"] == "final_error" and scored["estimators"]["mine"]["final_error_m"] < 20.0
    bag = read_bag(tmp_path / "bag")
    steps = list(range(41))
    for topic in ("/truth/state", "/ro/measurement", "/relay/estimate", "/smooth/estimate", "/mine/estimate"):
        assert sorted(m.step for _, m in bag[topic]) == steps, topic  # no message lost on any hop
    ranges = np.array([m.value[0] for _, m in sorted(bag["/ro/measurement"], key=lambda tm: tm[1].step)])
    last = max(bag["/smooth/estimate"], key=lambda tm: tm[1].step)[1]
    assert last.state[0] == pytest.approx(ranges.mean(), rel=1e-12)
    truth = {m.step: np.array(m.state) for _, m in bag["/truth/state"]}
    errors = [np.linalg.norm(np.array(m.state[:3]) - truth[m.step][:3]) for _, m in bag["/mine/estimate"]]
    assert max(errors) < 20.0  # the registered filter tracks (P0 sigma 5 m per axis, range-only)


def test_without_the_plugin_the_scenario_stops_naming_what_is_missing(tmp_path):
    res = script("launch.py", str(EXAMPLE / "plugin_demo.yaml"), "--out", str(tmp_path))
    assert res.returncode == 2
    assert "unknown key(s) 'relays', 'smoothers'" in res.stderr  # sections nobody registered
    cfg = yaml.safe_load((EXAMPLE / "plugin_demo.yaml").read_text())
    del cfg["relays"], cfg["smoothers"]
    (tmp_path / "no_stages.yaml").write_text(yaml.safe_dump(cfg))
    res = script("launch.py", str(tmp_path / "no_stages.yaml"), "--out", str(tmp_path / "a"))
    assert res.returncode == 2 and "'filters.mine.type' must be one of" in res.stderr and "inflated_ekf" in res.stderr
    cfg["filters"]["mine"] = {"type": "ekf"}
    (tmp_path / "no_stages.yaml").write_text(yaml.safe_dump(cfg))
    res = script("launch.py", str(tmp_path / "no_stages.yaml"), "--out", str(tmp_path / "a"))
    assert res.returncode == 2 and "'scoring.metric' must be one of" in res.stderr and "final_error" in res.stderr
    cfg["scoring"] = {"metric": "errors"}
    (tmp_path / "no_stages.yaml").write_text(yaml.safe_dump(cfg))
    res = script("launch.py", str(tmp_path / "no_stages.yaml"), "--out", str(tmp_path / "b"))
    assert res.returncode == 2
    assert "'sensors.ro.type' must be one of" in res.stderr and "range_only" in res.stderr
