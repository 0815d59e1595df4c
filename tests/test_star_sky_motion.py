"""Attitude truth of a camera fixed in LVLH on the paper's orbit: the two image motions and the jitter."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench_engine.config import apply_overrides, load_scenario
from orbit_sim.truth import build_truth
from star_tracker.camera import DEFAULT_CAMERA
from star_tracker.sky_motion import CircularOrbit, jitter_rates, lvlh_attitude, orbit_truth

ORBIT = CircularOrbit(700e3, 30.0, raan_deg=40.0, arg_latitude0_deg=10.0)


def test_the_orbit_frame_is_orthonormal_and_has_the_inclination():
    r, t, h = ORBIT.axes(np.linspace(0, 6000, 7))
    for a, b in ((r, t), (r, h), (t, h)):
        np.testing.assert_allclose(np.einsum("ki,ki->k", a, b), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.cross(r, t), h, atol=1e-12)
    assert np.degrees(np.arccos(h[0, 2])) == pytest.approx(30.0)
    assert 2 * np.pi / ORBIT.mean_motion / 60 == pytest.approx(98.77, abs=0.05)  # 700 km
    assert CircularOrbit(period_s=5400.0).mean_motion == pytest.approx(2 * np.pi / 5400)


@pytest.mark.parametrize("boresight", ["zenith", "normal"])
def test_attitudes_are_rotations_and_the_body_rate_is_their_derivative(boresight):
    truth = orbit_truth(ORBIT, 200, 0.1, boresight, jitter_deg_s=0.5, rng=np.random.default_rng(1))
    A, w = truth.attitude, truth.rate
    np.testing.assert_allclose(A @ A.transpose(0, 2, 1), np.broadcast_to(np.eye(3), A.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(A), 1.0)
    for k in range(199):  # A(t + dt) = exp(−[ω×] dt) A(t) to second order in dt (with jitter the
        step = Rotation.from_rotvec(-w[k] * 0.1).as_matrix() @ A[k]  # zenith case's rate turns: ~n J dt²/2)
        np.testing.assert_allclose(step, A[k + 1], atol=1e-7)
        wrong = Rotation.from_rotvec(w[k] * 0.1).as_matrix() @ A[k]
        assert np.abs(wrong - A[k + 1]).max() > 1e-5
    np.testing.assert_allclose(truth.quaternions[:, 0] >= 0, True)


def test_a_zenith_camera_sees_the_sky_drift_in_straight_lines_and_a_normal_one_sees_it_turn():
    n = ORBIT.mean_motion
    f = DEFAULT_CAMERA.focal_px
    r = np.array([[0.02, -0.03, 1.0], [-0.05, 0.04, 1.0]])
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    A, _ = lvlh_attitude(ORBIT, np.array([0.0]), "zenith")
    stars = r @ A[0]  # stars seen at r in the first frame
    A2, _ = lvlh_attitude(ORBIT, np.array([0.0, 10.0]), "zenith")
    uv = DEFAULT_CAMERA.project(stars @ A2[1].T) - DEFAULT_CAMERA.project(stars @ A2[0].T)
    assert np.all(uv[:, 0] < 0) and np.allclose(uv[:, 0], -f * n * 10.0, rtol=0.01)
    assert np.all(np.abs(uv[:, 1]) < 0.02 * np.abs(uv[:, 0]))
    A3, _ = lvlh_attitude(ORBIT, np.array([0.0, 100.0]), "normal")
    stars = r @ A3[0]
    p0 = DEFAULT_CAMERA.project(stars @ A3[0].T) - DEFAULT_CAMERA.centre
    p1 = DEFAULT_CAMERA.project(stars @ A3[1].T) - DEFAULT_CAMERA.centre
    angle = np.arctan2(p1[:, 1], p1[:, 0]) - np.arctan2(p0[:, 1], p0[:, 0])
    np.testing.assert_allclose(angle, -n * 100.0, rtol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(p1, axis=1), np.linalg.norm(p0, axis=1), rtol=1e-12)


def test_jitter_is_uniform_within_its_amplitude_and_held_for_ten_frames():
    rates = jitter_rates(400, 0.5, np.random.default_rng(3))
    blocks = rates.reshape(40, 10)
    assert np.all(blocks == blocks[:, :1])
    assert np.all(np.abs(rates) <= np.radians(0.5)) and len(np.unique(blocks[:, 0])) == 40
    assert np.std(blocks[:, 0]) == pytest.approx(np.radians(0.5) / np.sqrt(3), rel=0.3)
    truth = orbit_truth(ORBIT, 400, 0.1, "zenith", jitter_deg_s=0.5, rng=np.random.default_rng(3))
    np.testing.assert_allclose(np.diff(truth.jitter_angle), rates[:-1] * 0.1)
    np.testing.assert_allclose(truth.rate[:, 2], rates)
    np.testing.assert_array_equal(truth.jitter_rate, rates)
    calm = orbit_truth(ORBIT, 400, 0.1, "zenith")
    assert np.all(calm.jitter_angle == 0) and np.allclose(calm.rate, [0, ORBIT.mean_motion, 0])


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError):
        lvlh_attitude(ORBIT, np.array([0.0]), "sideways")
    with pytest.raises(ValueError):
        orbit_truth(ORBIT, 10, 0.1, jitter_deg_s=0.1)  # no generator
    with pytest.raises(ValueError):
        jitter_rates(10, 0.1, np.random.default_rng(0), hold=0)


def test_each_run_seed_draws_its_own_jitter_unless_the_scenario_fixes_it():
    cfg = apply_overrides(load_scenario("star_tracker"), ["time.duration=2.0"])
    rates = {seed: build_truth({**cfg, "seed": seed}).states[:, 4:] for seed in (0, 1)}
    assert not np.allclose(rates[0], rates[1])  # Monte Carlo runs see different jitter
    np.testing.assert_array_equal(build_truth({**cfg, "seed": 1}).states, build_truth({**cfg, "seed": 1}).states)
    fixed = apply_overrides(cfg, ["truth.jitter_seed=5"])
    np.testing.assert_array_equal(build_truth({**fixed, "seed": 0}).states, build_truth({**fixed, "seed": 1}).states)
