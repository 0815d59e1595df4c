"""The star_tracker study through the graph (real rclpy/DDS, one process per node), read back with rosbags; its
scenario under arbitrary overrides; and the node cores (camera, tracker) on bad frames."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from graph_helpers import read_bag, script, stamp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench_engine.config import ScenarioError, apply_overrides, load_scenario, override_strings, select_variant
from bench_engine.graph import build_graph, resolve_estimators
from bench_engine.inprocess import run_in_process
from bench_engine.launcher import validate
from bench_eval.sweep import load_grid
from bench_studies.star_tracker.report import paper_case
from star_tracker.attitude import error_angle, matrix_from_quaternion
from star_tracker.camera_stage import STAR_CAMERA, camera_config
from star_tracker.catalogue import ARCSEC, load_catalogue
from star_tracker.sky_motion import CircularOrbit, orbit_truth
from star_tracker.star_camera import catalogue_of
from star_tracker.tracker_stage import StarTrackerStage

TRACKERS = ["sna_triad", "sna_wahba", "jpdaf_triad", "jpdaf_wahba"]


def test_short_run_through_the_graph_is_recorded_and_scored(tmp_path):
    out = tmp_path / "run"
    res = script("launch.py", "star_tracker", "--variant", "short,faults", "--out", str(out), "--json", timeout=240)
    assert res.returncode == 0, res.stdout + res.stderr
    bag = read_bag(out / "bag")
    steps = 100
    assert len(bag["/truth/state"]) == steps
    truth = bag["/truth/state"][0][1]
    assert list(truth.labels) == ["qw", "qx", "qy", "qz", "wx", "wy", "wz"] and truth.header.frame_id == "icrs"
    meas, star_truth = bag["/camera/measurement"], bag["/camera/star_truth"]
    assert len(meas) == len(star_truth) == steps
    for (_, m), (_, s) in zip(meas, star_truth):
        assert m.step == s.step and len(m.x) == len(s.x) == len(m.magnitude) == len(s.star_id)
        assert len(m.star_id) == 0  # the measurement carries no truth
    assert any(np.any(np.asarray(s.star_id) < 0) for _, s in star_truth)  # false stars are labelled
    assert bag["/camera/measurement"][0][1].header.frame_id == "camera"
    for name in TRACKERS:
        est = [m for _, m in bag[f"/{name}/estimate"]]
        assert len(bag[f"/{name}/stars"]) == steps
        assert len(est) >= 0.9 * steps and list(est[0].labels) == ["qw", "qx", "qy", "qz"]
        assert est[0].header.frame_id == "icrs" and len(est[0].covariance) == 9
        assert all(abs(np.linalg.norm(m.state) - 1.0) < 1e-9 and m.state[0] >= 0 for m in est)
        assert [stamp(m) for m in est] == sorted(stamp(m) for m in est)
    scores = json.loads(res.stdout[res.stdout.index("{") :])["estimators"]
    for name in TRACKERS:
        block = scores[name]
        assert math.isfinite(block["rms_arcsec"]) and 0.1 < block["rms_arcsec"] < 120.0
        assert block["identification_rate"] > 0.8 and block["false_ids"] < 0.5
        assert 0.0 <= block["first_fix_s"] < 1.0 and block["solved"] > 0.9
        assert 0.5 < block["nees"] < 10.0
    assert scores["jpdaf_wahba"]["rms_arcsec"] < scores["sna_triad"]["rms_arcsec"]
    # the graph gives what the same cores give in-process, bit for bit (same seed, same frames)
    cfg = select_variant(load_scenario("star_tracker"), "short,faults")
    items = run_in_process(cfg, seed=1).items
    for name in TRACKERS:
        graph = {
            m.step: (np.asarray(m.state), np.asarray(m.covariance), list(m.diagnostic_values))
            for _, m in bag[f"/{name}/estimate"]
        }
        local = {e.step: (e.x, e.P.ravel(), list(e.diagnostics.values())) for e in items[f"/{name}/estimate"]}
        assert graph.keys() == local.keys()
        for step, (x, P, d) in local.items():
            assert np.array_equal(graph[step][0], x) and np.array_equal(graph[step][1], P) and graph[step][2] == d


PATHS = None


def _paths() -> list[str]:
    def leaves(node, prefix=()):
        if isinstance(node, dict) and node:
            return [p for k, v in node.items() for p in leaves(v, prefix + (str(k),))]
        return [".".join(prefix)] if prefix else []

    return [p for p in leaves(load_scenario("star_tracker")) if not p.startswith(("sweeps", "variants", "description"))]


VALUES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**12), 10**12),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),
    st.lists(st.floats(-1e3, 1e3), max_size=4),
    st.dictionaries(st.text(max_size=4), st.integers(), max_size=2),
)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@given(data=st.data())
def test_any_override_gives_a_run_plan_or_a_clean_error(data):
    paths = _paths()
    keys = data.draw(
        st.lists(
            st.one_of(st.sampled_from(paths), st.sampled_from(paths).map(lambda p: p + ".extra")),
            min_size=1,
            max_size=3,
            unique=True,
        )
    )
    overrides = {k: data.draw(VALUES) for k in keys}
    try:
        cfg = apply_overrides(load_scenario("star_tracker"), override_strings(overrides))
        filters = resolve_estimators(cfg, None)
        validate(cfg, filters, "truth")
        build_graph(cfg, filters)
    except ScenarioError as err:
        assert str(err) and "\n" not in str(err).strip()


def test_every_variant_and_sweep_cell_resolves():
    cfg = load_scenario("star_tracker")
    for variant in cfg["variants"]:
        one = select_variant(cfg, variant)
        validate(one, resolve_estimators(one, None), "truth")
    grid = load_grid("star_tracker", "tables")
    assert len(grid.cells) == 18
    cases = [paper_case(c.cfg) for c in grid.cells]
    assert all(cases) and len({(c["table"], c["sigma"]) for c in cases}) == 18
    assert len(load_grid("star_tracker", "process_noise").cells) == 10


# ------------------------------------------------------------------------------------------- node cores
def _cores(variant: str = "short"):
    cfg = select_variant(load_scenario("star_tracker"), variant)
    run = {"seed": 3}
    return cfg, STAR_CAMERA.stage(cfg, "camera", run), {n: StarTrackerStage(cfg, n, run) for n in TRACKERS}


def _truth(cfg, steps):
    run = run_in_process(cfg, seed=3, until_step=steps - 1, roles=())
    return run.items["/truth/state"]


def _feed(trackers, frame):
    outs = {}
    for name, stage in trackers.items():
        outs[name] = dict(stage.on_input("/camera/measurement", frame))
    return outs


def test_bad_frames_give_no_attitude_with_a_reason_then_reacquire():
    """Empty frames (every star occluded), two stars only, a burst of 200 false stars and a 20-degree jump of the
    attitude: no exception, no estimate or a correct one, and the trackers re-acquire."""
    cfg, camera, trackers = _cores()
    logs = []
    for stage in trackers.values():
        stage.log = lambda level, text, logs=logs: logs.append(text)
    truth = _truth(cfg, 60)
    rng = np.random.default_rng(5)
    for k, sample in enumerate(truth):
        frame = dict(camera.on_input("/truth/state", sample))["/camera/measurement"]
        if 10 <= k < 13:  # every star occluded
            frame.xy, frame.magnitudes = np.zeros((0, 2)), np.zeros(0)
        elif k == 20:  # two stars only
            frame.xy, frame.magnitudes = frame.xy[:2], frame.magnitudes[:2]
        elif k == 30:  # a burst of false stars
            extra = rng.uniform(-0.17, 0.17, (200, 2))
            frame.xy = np.vstack([frame.xy, extra])
            frame.magnitudes = np.concatenate([frame.magnitudes, rng.uniform(2, 6, 200)])
        elif k == 40:  # a huge jitter step: the reported rate is 20 degrees off for one frame
            frame.body_rate = frame.body_rate + np.array([0.0, 0.0, np.radians(200.0)])
        A = matrix_from_quaternion(sample.state[:4])
        for name, out in _feed(trackers, frame).items():
            assert len(out["/" + name + "/stars"].star_id) == len(frame.xy)
            est = out.get(f"/{name}/estimate")
            if 10 <= k < 13 or k == 20:
                assert est is None
            if est is not None:  # never a wrong attitude presented as valid
                err = error_angle(matrix_from_quaternion(est.x), A) / ARCSEC
                assert err < 8 * math.sqrt(np.trace(est.P)) / ARCSEC + 5.0, (name, k, err)
    assert any("no attitude" in t for t in logs)
    for name, stage in trackers.items():
        assert stage.counts["reacquisitions"] >= 1, name
        assert stage.had_lock


def test_corrupt_catalogue_cache_is_rebuilt(tmp_path):
    cfg = apply_overrides(
        load_scenario("star_tracker"),
        [f"star_cameras.camera.cache_dir={tmp_path}", "star_cameras.camera.magnitude_limit=4.0"],
    )
    first = catalogue_of(camera_config(cfg, "camera"))
    cached = list(tmp_path.glob("hip_*.npz"))
    assert len(cached) == 1
    cached[0].write_bytes(b"not a catalogue")
    again = load_catalogue(4.0, 2025.0, 140.0, cache_dir=tmp_path)
    assert np.array_equal(again.ids, first.ids)
    cached[0].unlink()
    assert np.array_equal(load_catalogue(4.0, 2025.0, 140.0, cache_dir=tmp_path).ids, first.ids)


def test_truth_is_the_attitude_of_the_frames():
    cfg = select_variant(load_scenario("star_tracker"), "short")
    truth = _truth(cfg, 5)  # run seed 3, which also draws the jitter (truth.jitter_seed: null)
    ref = orbit_truth(
        CircularOrbit(raan_deg=30.0, arg_latitude0_deg=50.0), 5, 0.1, "zenith", 0.5, np.random.default_rng([3, 7])
    )
    assert np.allclose([s.state[:4] for s in truth], ref.quaternions)
    assert np.allclose([s.state[4:] for s in truth], ref.rate)


@pytest.mark.parametrize(
    "bad",
    [{"star_trackers.x.tracker": "kalman"}, {"truth.model": "cowell_j2"}, {"star_tracker_defaults.camera": "nope"}],
)
def test_bad_configuration_is_a_clean_error(bad):
    cfg = apply_overrides(load_scenario("star_tracker"), override_strings(bad))
    with pytest.raises(ScenarioError):
        filters = resolve_estimators(cfg, None)
        validate(cfg, filters, "truth")
