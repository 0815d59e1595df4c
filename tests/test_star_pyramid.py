"""Lost-in-space identification with the Pyramid algorithm: known patterns, frames with noise and false
stars, and frames it must refuse (too few stars, only false stars, a mirrored sky) with a reason."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from star_tracker.attitude import error_angle, error_vector
from star_tracker.camera import DEFAULT_CAMERA
from star_tracker.catalogue import ARCSEC, load_catalogue
from star_tracker.frames import FALSE_STAR, random_attitude, simulate_frame
from star_tracker.pyramid import UNIDENTIFIED, PyramidIdentifier, triangle_order


@pytest.fixture(scope="module")
def catalogue(tmp_path_factory):
    return load_catalogue(6.0, cache_dir=tmp_path_factory.mktemp("cache"))


@pytest.fixture(scope="module")
def pyramid(catalogue):
    return PyramidIdentifier(catalogue, DEFAULT_CAMERA, sigma_px=0.2)


def test_the_triangle_order_visits_every_triangle_once_changing_all_stars():
    tri = list(triangle_order(7))
    assert len(tri) == len(set(tri)) == 35 and all(i < j < k for i, j, k in tri)
    assert tri[:3] == [(0, 1, 2), (1, 2, 3), (2, 3, 4)]


def test_a_noise_free_frame_is_identified_exactly(catalogue, pyramid):
    A = Rotation.from_euler("zyx", [40.0, -20.0, 10.0], degrees=True).as_matrix()
    idx, uv = DEFAULT_CAMERA.stars_in_view(catalogue, A)
    result = pyramid.identify(uv, catalogue.magnitudes[idx])
    assert result.ok and result.reason == ""
    np.testing.assert_array_equal(result.index, idx)
    np.testing.assert_array_equal(result.hip(catalogue), catalogue.ids[idx])
    assert error_angle(result.attitude.matrix, A) < 0.01 * ARCSEC
    assert result.false_alarm < 1e-20


def test_a_known_pattern_in_any_centroid_order_is_identified(catalogue, pyramid):
    rng = np.random.default_rng(11)
    A = random_attitude(rng)
    idx, uv = DEFAULT_CAMERA.stars_in_view(catalogue, A)
    perm = rng.permutation(len(idx))
    result = pyramid.identify(uv[perm])                       # no magnitudes: the given order is used
    assert result.ok
    np.testing.assert_array_equal(result.index, idx[perm])
    other = pyramid.identify(uv[perm], np.zeros(3))            # magnitudes that do not fit are ignored
    np.testing.assert_array_equal(other.index, idx[perm])


@pytest.mark.parametrize("seed", range(3))
def test_noisy_frames_with_false_stars_are_identified_and_the_false_stars_rejected(catalogue, pyramid, seed):
    rng = np.random.default_rng(100 + seed)
    for _ in range(40):
        A = random_attitude(rng)
        frame = simulate_frame(catalogue, DEFAULT_CAMERA, A, rng, sigma_px=0.2, n_false=2)
        result = pyramid.identify(frame.uv, frame.magnitudes)
        assert result.ok, result.reason
        real = frame.truth != FALSE_STAR
        np.testing.assert_array_equal(result.index[~real], UNIDENTIFIED)
        # every identified star is right, and (σ = 0.2 px) all but a rare 6σ outlier are identified
        ident = result.index >= 0
        np.testing.assert_array_equal(result.index[ident], frame.truth[ident])
        assert ident.sum() >= real.sum() - 1
        e = error_vector(result.attitude.matrix, A)
        assert e @ np.linalg.solve(result.attitude.covariance, e) < 30.0       # consistent with its covariance


def test_another_camera_and_catalogue_work_the_same_way(tmp_path):
    from star_tracker.camera import Camera
    camera = Camera(12.0, 2048, 1536)
    catalogue = load_catalogue(6.5, cache_dir=tmp_path)
    pyramid = PyramidIdentifier(catalogue, camera, sigma_px=0.3)
    rng = np.random.default_rng(31)
    for _ in range(15):
        A = random_attitude(rng)
        frame = simulate_frame(catalogue, camera, A, rng, sigma_px=0.3, n_false=2)
        result = pyramid.identify(frame.uv, frame.magnitudes)
        if len(frame) - frame.n_false >= 6:
            assert result.ok, result.reason
        if result.ok:
            ident = result.index >= 0
            np.testing.assert_array_equal(result.index[ident], frame.truth[ident])


def test_missed_stars_and_a_burst_of_false_stars_still_give_the_right_answer_or_none(catalogue, pyramid):
    rng = np.random.default_rng(7)
    solved = 0
    for _ in range(30):
        A = random_attitude(rng)
        frame = simulate_frame(catalogue, DEFAULT_CAMERA, A, rng, sigma_px=0.2, p_detect=0.7, n_false=15)
        result = pyramid.identify(frame.uv, frame.magnitudes)
        if result.ok:
            solved += 1
            ident = result.index >= 0
            np.testing.assert_array_equal(result.index[ident], frame.truth[ident])
            assert error_angle(result.attitude.matrix, A) < 100 * ARCSEC
        else:
            assert result.reason and result.attitude is None
    assert solved >= 25


@pytest.mark.parametrize("n", [0, 1, 3])
def test_too_few_stars_fail_with_a_reason(catalogue, pyramid, n):
    A = random_attitude(np.random.default_rng(n))
    _, uv = DEFAULT_CAMERA.stars_in_view(catalogue, A)
    result = pyramid.identify(uv[:n])
    assert not result.ok and "too few" in result.reason and result.attitude is None
    assert result.index.shape == (n,) and np.all(result.index == UNIDENTIFIED)


def test_a_frame_of_false_stars_only_is_refused(pyramid):
    rng = np.random.default_rng(3)
    for _ in range(3):
        uv = rng.uniform(0, 1024, (30, 2))
        result = pyramid.identify(uv)
        assert not result.ok and "no confirmed triangle" in result.reason


def test_a_mirrored_sky_is_refused(catalogue, pyramid):
    A = random_attitude(np.random.default_rng(21))
    idx, uv = DEFAULT_CAMERA.stars_in_view(catalogue, A)
    mirrored = uv.copy()
    mirrored[:, 0] = DEFAULT_CAMERA.width - mirrored[:, 0]     # the same angles, the other handedness
    assert not pyramid.identify(mirrored, catalogue.magnitudes[idx]).ok


def test_non_finite_centroids_are_ignored(catalogue, pyramid):
    A = random_attitude(np.random.default_rng(5))
    idx, uv = DEFAULT_CAMERA.stars_in_view(catalogue, A)
    uv = uv.copy()
    uv[2] = np.nan
    result = pyramid.identify(uv)
    assert result.ok and result.index[2] == UNIDENTIFIED
    keep = np.arange(len(idx)) != 2
    np.testing.assert_array_equal(result.index[keep], idx[keep])


def test_matching_from_a_known_attitude_identifies_new_stars(catalogue, pyramid):
    rng = np.random.default_rng(8)
    A = random_attitude(rng)
    frame = simulate_frame(catalogue, DEFAULT_CAMERA, A, rng, sigma_px=0.2, n_false=3)
    index, dist = pyramid.match(DEFAULT_CAMERA.unproject(frame.uv), A)
    real = frame.truth >= 0
    np.testing.assert_array_equal(index[real], frame.truth[real])
    assert np.all(index[~real] == UNIDENTIFIED) and np.all(np.isinf(dist[~real]))
