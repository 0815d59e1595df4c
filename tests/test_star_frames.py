"""Simulated star-camera frames: what is in them and their truth."""

from __future__ import annotations

import numpy as np
import pytest

from star_tracker.camera import DEFAULT_CAMERA
from star_tracker.catalogue import load_catalogue
from star_tracker.frames import FALSE_STAR, random_attitude, simulate_frame


@pytest.fixture(scope="module")
def catalogue(tmp_path_factory):
    return load_catalogue(6.0, cache_dir=tmp_path_factory.mktemp("cache"))


def test_a_frame_holds_the_stars_in_view_with_noise_and_its_false_stars(catalogue):
    rng = np.random.default_rng(1)
    A = random_attitude(rng)
    idx, uv = DEFAULT_CAMERA.stars_in_view(catalogue, A)
    frame = simulate_frame(catalogue, DEFAULT_CAMERA, A, np.random.default_rng(2), sigma_px=0.3, n_false=4)
    real = frame.truth != FALSE_STAR
    assert frame.n_false == 4 and len(frame) == real.sum() + 4
    assert set(frame.truth[real].tolist()) <= set(idx.tolist()) and real.sum() >= len(idx) - 2  # edge losses
    truth_uv = dict(zip(idx.tolist(), uv))
    err = np.array([frame.uv[k] - truth_uv[i] for k, i in enumerate(frame.truth) if i >= 0])
    assert np.std(err) == pytest.approx(0.3, rel=0.25)
    assert np.all(np.diff(frame.magnitudes) >= 0)  # brightest first
    assert DEFAULT_CAMERA.in_image(frame.uv).all()
    np.testing.assert_array_equal(frame.attitude, A)


def test_detection_probability_and_poisson_false_stars(catalogue):
    rng = np.random.default_rng(3)
    seen, total, false = 0, 0, []
    for _ in range(200):
        A = random_attitude(rng)
        total += len(DEFAULT_CAMERA.stars_in_view(catalogue, A)[0])
        frame = simulate_frame(catalogue, DEFAULT_CAMERA, A, rng, sigma_px=0.0, p_detect=0.8, false_rate=3.0)
        seen += int(np.sum(frame.truth >= 0))
        false.append(frame.n_false)
    assert seen / total == pytest.approx(0.8, abs=0.02)
    assert np.mean(false) == pytest.approx(3.0, abs=0.3) and np.var(false) == pytest.approx(3.0, rel=0.3)


def test_the_same_seed_gives_the_same_frame_and_bad_p_detect_is_refused(catalogue):
    A = random_attitude(np.random.default_rng(0))
    f1 = simulate_frame(catalogue, DEFAULT_CAMERA, A, np.random.default_rng(9), n_false=2, p_detect=0.9)
    f2 = simulate_frame(catalogue, DEFAULT_CAMERA, A, np.random.default_rng(9), n_false=2, p_detect=0.9)
    np.testing.assert_array_equal(f1.uv, f2.uv)
    np.testing.assert_array_equal(f1.truth, f2.truth)
    with pytest.raises(ValueError):
        simulate_frame(catalogue, DEFAULT_CAMERA, A, np.random.default_rng(9), p_detect=1.5)
