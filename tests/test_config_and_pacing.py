"""Scenario loading/validation, graph wiring and the lock-step pacing rules (no ROS needed)."""

from __future__ import annotations

import pytest

from bench_engine.config import ScenarioError, Section, apply_overrides, load_scenario, select_variant
from bench_engine.graph import build_graph
from bench_engine.launcher import validate
from bench_engine.lockstep import Pacer
from bench_engine.timegrid import build_time
from tracker_filters.filter_settings import filter_config


def test_override_parses_yaml_values_and_creates_sections() -> None:
    cfg = apply_overrides({"a": {"b": 1}}, ["a.b=2.5", "a.c=[1, 2]", "d.e=true", "f=1e-3"])
    assert cfg == {"a": {"b": 2.5, "c": [1, 2]}, "d": {"e": True}, "f": "1e-3"}
    with pytest.raises(ScenarioError, match="'a.b' is a value, not a section"):
        apply_overrides({"a": {"b": 1}}, ["a.b.c=1"])
    with pytest.raises(ScenarioError, match="must look like key.path=value"):
        apply_overrides({}, ["nonsense"])


def test_section_reads_typed_values_and_rejects_unknown_keys() -> None:
    sec = Section({"sigma": "1e-3", "p": 0.5, "name": "x", "typo": 1}, "sensors.radar")
    assert sec.positive("sigma") == pytest.approx(1e-3)  # YAML 1.1 reads 1e-3 as a string
    assert sec.get("p", float) == 0.5
    assert sec.choice("name", ["x", "y"]) == "x"
    with pytest.raises(ScenarioError, match=r"unknown key\(s\) 'sensors.radar.typo'.*allowed: name, p, sigma"):
        sec.finish()
    with pytest.raises(ScenarioError, match="'s.flag' must be a number, got a boolean True"):
        Section({"flag": True}, "s").positive("flag")
    with pytest.raises(ScenarioError, match="missing key 's.k'"):
        Section({}, "s").get("k", float)


def test_leo_radar_validates_and_its_variant_changes_the_angles() -> None:
    cfg = load_scenario("leo_radar")
    validate(cfg, ["ekf", "ukf"], "truth")
    variant = select_variant(cfg, "table3_angles")
    assert variant["sensors"]["radar"]["sigma_azimuth"] == pytest.approx(4.35e-4)
    assert cfg["sensors"]["radar"]["sigma_azimuth"] == pytest.approx(0.017)


def test_any_registered_filter_type_can_be_named_on_the_command_line() -> None:
    cfg = load_scenario("leo_radar")
    assert filter_config(cfg, "kf")["type"] == "kf"
    assert filter_config(cfg, "ukf")["params"]["alpha"] == cfg["filters"]["ukf"]["params"]["alpha"]
    ekf = filter_config(cfg, "ekf")["dynamics"]  # the filter's own value over filter_defaults'
    assert ekf["sigma_accel"] == cfg["filters"]["ekf"]["dynamics"]["sigma_accel"]
    assert ekf["sigma_accel"] != cfg["filter_defaults"]["dynamics"]["sigma_accel"]
    assert filter_config(cfg, "ukf")["dynamics"]["model"] == "orbit_j2"  # from filter_defaults


def test_graph_expects_every_subscriber_before_starting() -> None:
    graph = build_graph(load_scenario("leo_radar"), ["ekf", "ukf"], record=True)
    assert [n.name for n in graph.nodes] == ["truth", "radar", "ekf", "ukf", "recorder"]
    assert graph.expected_subscribers("/truth/state") == 2  # radar + recorder
    assert graph.expected_subscribers("/radar/measurement") == 3  # ekf + ukf + recorder
    assert graph.expected_subscribers("/ukf/estimate") == 1
    assert set(graph.data_topics()) == {
        "/truth/state",
        "/clock",
        "/radar/measurement",
        "/ekf/estimate",
        "/ukf/estimate",
        "/truth/odometry",
        "/truth/markers",
        *(
            f"/{n}/{v}"
            for n in ("ekf", "ukf")  # standard views (bench_engine.views)
            for v in ("odometry", "diagnostics", "markers")
        ),
    }
    assert graph.expected_subscribers("/ukf/odometry") == 1  # the recorder


def test_time_grid_uses_integer_nanoseconds() -> None:
    grid = build_time({"time": {"start": 4320.8, "dt": 0.1, "duration": 420.0}})
    assert grid.steps == 4201
    assert grid.t_ns(4200) == 4320_800_000_000 + 420_000_000_000


RADAR = {"radar": ["/truth/state"]}


def test_strict_pacing_waits_for_sensor_and_filters() -> None:
    pacer = Pacer({**RADAR, "ekf": ["/radar/measurement"], "ukf": ["/radar/measurement"]}, window=0)
    assert pacer.can_publish()
    pacer.on_published("/truth/state")  # step 0
    assert not pacer.can_publish()  # radar has not handled step 0
    pacer.on_ack("radar", 1, {"/radar/measurement": 1})  # published one measurement
    assert not pacer.can_publish()  # the filters have not consumed it
    pacer.on_ack("ekf", 1, {"/ekf/estimate": 1})
    pacer.on_ack("ukf", 1, {})
    assert pacer.can_publish() and pacer.complete()
    pacer.on_ack("someone_else", 9, {"/radar/measurement": 9})  # foreign acks are ignored
    pacer.on_published("/truth/state")  # step 1
    assert not pacer.complete()


def test_window_lets_the_source_run_ahead_by_a_bounded_amount() -> None:
    pacer = Pacer({**RADAR, "ukf": ["/radar/measurement"]}, window=3)
    for _ in range(4):  # steps 0..3
        assert pacer.can_publish()
        pacer.on_published("/truth/state")
    assert not pacer.can_publish()  # step 4 would be 4 ahead of the radar
    pacer.on_ack("radar", 4, {"/radar/measurement": 4})
    assert pacer.backlog("ukf") == 4 and not pacer.can_publish()
    pacer.on_ack("ukf", 1, {})
    assert pacer.can_publish()


def test_replay_pacing_counts_its_own_publications() -> None:
    pacer = Pacer({"ukf": ["/radar/measurement"]}, window=0)
    pacer.on_published("/radar/measurement")
    assert not pacer.can_publish()
    pacer.on_ack("ukf", 1, {})
    assert pacer.can_publish() and pacer.complete()


def test_pacing_a_three_stage_pipeline_counts_every_hop() -> None:
    """camera -> identifier -> tracker: the source waits for the last stage, and completion needs every hop."""
    pacer = Pacer(
        {"camera": ["/truth/state"], "ident": ["/camera/measurement"], "track": ["/ident/estimate"]}, window=0
    )
    pacer.on_published("/truth/state")
    pacer.on_ack("camera", 1, {"/camera/measurement": 1})
    pacer.on_ack("ident", 1, {"/ident/estimate": 2})  # one frame in, two outputs
    assert pacer.backlog("track") == 2 and not pacer.can_publish() and not pacer.complete()
    pacer.on_ack("track", 2, {})
    assert pacer.can_publish() and pacer.complete()
