"""The pinhole star camera: projection round trips, geometry, and the catalogue stars in view."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from star_tracker.camera import DEFAULT_CAMERA, Camera
from star_tracker.catalogue import load_catalogue


@pytest.fixture(scope="module")
def catalogue(tmp_path_factory):
    return load_catalogue(6.0, cache_dir=tmp_path_factory.mktemp("cache"))


@pytest.mark.parametrize("camera", [DEFAULT_CAMERA, Camera(15.0, 2048, 1536), Camera(8.0, 640, 480)])
def test_pixels_to_directions_and_back_round_trip(camera):
    rng = np.random.default_rng(0)
    uv = rng.uniform([0, 0], [camera.width, camera.height], (500, 2))
    v = camera.unproject(uv)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0)
    np.testing.assert_allclose(camera.project(v), uv, atol=1e-9)
    # and from directions: scaled directions project the same
    np.testing.assert_allclose(camera.project(3.7 * v), uv, atol=1e-9)


def test_tangent_plane_coordinates_are_the_directions_x_over_z_and_y_over_z():
    rng = np.random.default_rng(4)
    uv = rng.uniform(0, 1024, (50, 2))
    xy = DEFAULT_CAMERA.to_tangent(uv)
    v = DEFAULT_CAMERA.unproject(uv)
    np.testing.assert_allclose(xy, v[:, :2] / v[:, 2:], atol=1e-15)
    np.testing.assert_allclose(DEFAULT_CAMERA.from_tangent(xy), uv, atol=1e-9)


def test_the_geometry_follows_the_field_of_view():
    cam = Camera(20.0, 1024, 1024)
    assert cam.focal_px == pytest.approx(512 / np.tan(np.radians(10)))
    edge = cam.unproject(np.array([[1024.0, 512.0]]))[0]
    assert np.degrees(np.arccos(edge[2])) == pytest.approx(10.0)  # half the FOV at the edge
    corner = cam.unproject(np.array([[0.0, 0.0]]))[0]
    assert np.arccos(corner[2]) == pytest.approx(cam.half_diagonal)
    opposite = cam.unproject(np.array([[1024.0, 1024.0]]))[0]
    assert np.arccos(corner @ opposite) == pytest.approx(cam.max_separation)
    # +x along u, +y along v, +z the boresight
    np.testing.assert_allclose(cam.project(np.array([[0.0, 0.0, 1.0]])), [[512.0, 512.0]])
    right_down = cam.project(np.array([[0.01, 0.02, 1.0]]))[0]
    assert right_down[0] > 512 and right_down[1] > 512
    assert cam.ifov * 206265 == pytest.approx(71.04, abs=0.01)


def test_directions_behind_the_camera_do_not_project():
    uv = DEFAULT_CAMERA.project(np.array([[0.0, 0.0, -1.0], [0.1, 0.0, 0.0], [0.0, 0.1, 1.0]]))
    assert np.isnan(uv[:2]).all() and np.isfinite(uv[2]).all()
    assert not DEFAULT_CAMERA.in_image(uv[:2]).any()


def test_bad_cameras_are_refused():
    with pytest.raises(ValueError):
        Camera(0.0)
    with pytest.raises(ValueError):
        Camera(20.0, 0, 10)


def test_stars_in_view_equal_a_brute_force_projection_of_the_whole_catalogue(catalogue):
    rng = np.random.default_rng(1)
    for camera in (DEFAULT_CAMERA, Camera(12.0, 1280, 720)):
        for _ in range(20):
            A = Rotation.random(random_state=rng).as_matrix()
            idx, uv = camera.stars_in_view(catalogue, A)
            b = catalogue.vectors @ A.T
            uv_all = camera.project(b)
            want = np.flatnonzero((b[:, 2] > 0) & camera.in_image(uv_all))
            np.testing.assert_array_equal(idx, want)
            np.testing.assert_allclose(uv, uv_all[want])
            assert np.all(np.diff(catalogue.magnitudes[idx]) >= 0)  # brightest first


def test_the_default_camera_sees_enough_stars_everywhere(catalogue):
    rng = np.random.default_rng(2)
    counts = [
        len(DEFAULT_CAMERA.stars_in_view(catalogue, Rotation.random(random_state=rng).as_matrix())[0])
        for _ in range(300)
    ]
    assert np.min(counts) >= 8 and 30 <= np.median(counts) <= 60
