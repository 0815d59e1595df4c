"""Lost-in-space identification with the Pyramid algorithm: known patterns, frames with noise and false
stars, and frames it must refuse (too few stars, only false stars, a mirrored sky) with a reason."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from star_tracker.attitude import error_angle, error_vector
from star_tracker.camera import DEFAULT_CAMERA, Camera
from star_tracker.catalogue import ARCSEC, angle_between, load_catalogue
from star_tracker.frames import FALSE_STAR, random_attitude, simulate_frame
from star_tracker.pyramid import UNIDENTIFIED, PyramidIdentifier, _Angles, _Near, triangle_order, triple_product


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
    result = pyramid.identify(uv[perm])  # no magnitudes: the given order is used
    assert result.ok
    np.testing.assert_array_equal(result.index, idx[perm])
    other = pyramid.identify(uv[perm], np.zeros(3))  # magnitudes that do not fit are ignored
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
        assert e @ np.linalg.solve(result.attitude.covariance, e) < 30.0  # consistent with its covariance


def test_another_camera_and_catalogue_work_the_same_way(tmp_path):
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
    mirrored[:, 0] = DEFAULT_CAMERA.width - mirrored[:, 0]  # the same angles, the other handedness
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


# ------------------------------------------------------------------------------------------------------------
# The Pyramid steps themselves, on star geometry built directly (no later stage may do their work for them).


def _noise_free_frame(catalogue, seed: int = 0):
    """Catalogue indices (brightest first) and camera-frame unit vectors b = A v of the stars in view."""
    A = Rotation.from_euler("zyx", [40.0 + 25.0 * seed, -20.0, 10.0], degrees=True).as_matrix()
    idx, _ = DEFAULT_CAMERA.stars_in_view(catalogue, A)
    return A, idx, catalogue.vectors[idx] @ A.T


def _theta(b):
    """The frame's angles as the identifier's steps take them (computed a column at a time)."""
    return _Angles(b)


def test_the_triangle_step_refuses_a_mirrored_triangle_by_its_handedness(catalogue, pyramid):
    """A mirror image has the same three angles as the catalogue triangle, so only the sign of the triple
    product tells them apart: the triangle step must return the true triangle for the real stars and refuse
    it for their mirror image (x -> -x in the camera frame), before any pyramid or attitude check."""
    checked = 0
    for seed in range(3):
        _, idx, b = _noise_free_frame(catalogue, seed)
        theta = _theta(b)
        for i, j, k in [(0, 1, 2), (1, 2, 3), (0, 2, 4)]:
            s_obs = triple_product(b[i], b[j], b[k])
            if abs(s_obs) < 1e-3:  # a flat triangle carries no handedness
                continue
            true = (idx[i], idx[j], idx[k])
            found = pyramid._triangle_candidates(b, theta, i, j, k, {})
            assert true in set(map(tuple, found)), f"true triangle {true} not among {found}"
            mirrored = b * np.array([-1.0, 1.0, 1.0])
            np.testing.assert_allclose(
                angle_between(mirrored[:, None], mirrored[None]), angle_between(b[:, None], b[None]), atol=1e-15
            )  # the same angles ...
            refused = pyramid._triangle_candidates(mirrored, theta, i, j, k, {})
            assert true not in set(map(tuple, refused)), "a mirrored triangle was taken for the real one"
            v = catalogue.vectors
            for a, bb, c in refused:  # ... and every candidate has its handedness
                assert np.sign(triple_product(v[a], v[bb], v[c])) == np.sign(triple_product(*mirrored[[i, j, k]]))
            checked += 1
    assert checked >= 6


def _fake_star(catalogue, pyramid, tri, X: int, sides: str):
    """A direction whose nearest catalogue star is X and whose angles to the triangle's catalogue stars equal
    X's on the named ``sides`` ("a", "b", "c" or two of them) only: moved along the circle about one triangle
    star (one side kept), or reflected through the plane of two of them (two sides kept). None when X does not
    give such a direction (the moved point must stay nearest to X, and be farther than two match radii)."""
    v = catalogue.vectors
    corners = dict(zip("abc", v[list(tri)]))
    x = v[X]
    if len(sides) == 1:
        axis = corners[sides]
        turn = 12.0 * pyramid.epsilon / np.sin(angle_between(axis, x))
        options = [Rotation.from_rotvec(s * turn * axis).as_matrix() @ x for s in (1.0, -1.0)]
    else:
        n = np.cross(corners[sides[0]], corners[sides[1]])
        n /= np.linalg.norm(n)
        options = [x - 2.0 * (x @ n) * n]
    for p in options:
        change = np.abs(angle_between(v[list(tri)], p) - angle_between(v[list(tri)], x))
        kept = "".join(s for s, d in zip("abc", change) if d <= pyramid.epsilon)
        sep = angle_between(p, x)
        if (
            kept == sides
            and catalogue.tree.query(p)[1] == X
            and 2.0 * pyramid.match_radius < sep < 40.0 * pyramid.match_radius
        ):
            return p
    return None


@pytest.mark.parametrize("sides", ["a", "b", "c", "ab", "ac", "bc"])
def test_a_fourth_star_confirms_only_when_all_three_of_its_angles_match(catalogue, pyramid, sides):
    """Step 2 (the pyramid): a fourth star confirms a triangle only if its nearest catalogue star is within ε
    of the observed angle on all three sides. A false star built to match one or two sides exactly (and the
    third by far more than ε) must not count as a confirmation; the real stars of the frame all do."""
    for seed in range(6):
        A, idx, b = _noise_free_frame(catalogue, seed)
        tri = tuple(int(i) for i in idx[:3])
        for X in idx[3:]:
            p = _fake_star(catalogue, pyramid, tri, int(X), sides)
            if p is not None:
                break
        else:
            continue
        keep = idx != X  # X itself is not in the frame, only the fake near it
        frame = np.vstack([b[keep], A @ p])
        result = pyramid._confirm(frame, _theta(frame), (0, 1, 2), tri)
        assert result is not None and result.ok
        real_others = int(keep.sum()) - 3
        assert result.stats["pyramid_confirmations"] == real_others, (
            f"a false star matching side(s) {sides} only was counted as a confirmation"
        )
        assert result.index[-1] == UNIDENTIFIED
        # the control: the real star X in the same place is a confirmation
        control = np.vstack([b[keep], b[idx == X]])
        assert (
            pyramid._confirm(control, _theta(control), (0, 1, 2), tri).stats["pyramid_confirmations"] == real_others + 1
        )
        return
    pytest.fail(f"no star of six frames gives a fake matching side(s) {sides} only")


def test_the_neighbourhood_search_answers_as_the_k_d_tree_or_not_at_all(catalogue, pyramid):
    """_Near (the brute-force nearest star around a candidate triangle's first star) gives the k-d tree's
    answer for directions near that star, and declines directions farther than its neighbourhood covers."""
    rng = np.random.default_rng(3)
    answered = declined = hits = 0
    for a in rng.choice(len(catalogue), 40, replace=False):
        near = _Near(pyramid, int(a))
        assert near.stars[-1] == a
        spread = rng.uniform(0.0, 0.5, 60)  # up to 29°: some beyond the neighbourhood's reach
        p = catalogue.vectors[a] + spread[:, None] * rng.normal(size=(60, 3))
        p /= np.linalg.norm(p, axis=1, keepdims=True)
        for bound in (pyramid._match_chord, pyramid._pyramid_chord):
            d, idx = catalogue.tree.query(p, k=1, distance_upper_bound=bound)
            for row in range(0, 60, 6):  # small batches: one far row makes the whole batch decline
                got = near(p[row : row + 6], bound)
                if got is None:
                    declined += 1
                    reach = np.linalg.norm(p[row : row + 6] - catalogue.vectors[a], axis=1).max() + bound
                    assert reach > near.reach_chord
                    continue
                answered += 1
                rows = np.isfinite(d[row : row + 6]).nonzero()[0]
                hits += len(rows)
                np.testing.assert_array_equal(got[0], rows)
                np.testing.assert_array_equal(got[1], idx[row : row + 6][rows])
    assert answered > 100 and declined > 100 and hits > 100
