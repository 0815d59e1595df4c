"""The per-frame star tracker core: lost-in-space, then SNA or JPDAF tracking with new stars handed over from
the attitude, TRIAD or all-star attitude; lost lock, empty frames, attitude jumps and bursts of false stars."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from star_tracker.attitude import error_angle, error_vector
from star_tracker.camera import DEFAULT_CAMERA
from star_tracker.catalogue import ARCSEC, load_catalogue
from star_tracker.frames import simulate_frame
from star_tracker.pipeline import StarTrackerPipeline
from star_tracker.pyramid import PyramidIdentifier
from star_tracker.sky_motion import CircularOrbit, orbit_truth

SIGMA = 0.05


@pytest.fixture(scope="module")
def sky(tmp_path_factory):
    catalogue = load_catalogue(6.0, cache_dir=tmp_path_factory.mktemp("cache"))
    return catalogue, PyramidIdentifier(catalogue, DEFAULT_CAMERA, sigma_px=SIGMA)


def run(sky, truth, frames, **options):
    catalogue, identifier = sky
    pipe = StarTrackerPipeline(
        catalogue, DEFAULT_CAMERA, SIGMA, identifier=identifier, clutter_density=2.0 / 1024**2, **options
    )
    out = []
    for k, frame in enumerate(frames):
        j = max(k - 1, 0)
        out.append(pipe.process(frame.uv, frame.magnitudes, truth.t[k], truth.rate[j], truth.jitter_rate[j]))
    return out


def sequence(sky, boresight, jitter, n=120, period_s=None, seed=0):
    rng = np.random.default_rng(seed)
    orbit = CircularOrbit(raan_deg=70.0, arg_latitude0_deg=20.0, period_s=period_s)
    truth = orbit_truth(orbit, n, 0.1, boresight, jitter, rng)
    frames = [
        simulate_frame(sky[0], DEFAULT_CAMERA, A, rng, sigma_px=SIGMA, p_detect=0.95, n_false=2) for A in truth.attitude
    ]
    return truth, frames


def check(results, frames):
    """Every frame has an attitude; the first from lost-in-space, the rest tracked; no centroid misidentified;
    returns the attitude errors (rad)."""
    assert all(r.ok for r in results), [r.reason for r in results if not r.ok][:3]
    assert results[0].mode == "lost_in_space"
    assert sum(r.mode == "lost_in_space" for r in results) <= 2
    errors = []
    for r, f in zip(results, frames):
        ident = r.index >= 0
        np.testing.assert_array_equal(r.index[ident], f.truth[ident])
        errors.append(error_angle(r.attitude.matrix, f.attitude))
    return np.array(errors)


@pytest.fixture(scope="module")
def drift(sky):
    return sequence(sky, "zenith", 0.5)


@pytest.mark.parametrize("tracker", ["sna", "jpdaf"])
@pytest.mark.parametrize("solver", ["wahba", "triad"])
def test_every_tracker_and_solver_tracks_a_jittering_drift(sky, drift, tracker, solver):
    truth, frames = drift
    results = run(sky, truth, frames, tracker=tracker, solver=solver, sigma_a=0.05)
    errors = check(results, frames)
    assert np.sqrt(np.mean(errors**2)) < (5.0 if solver == "wahba" else 30.0) * ARCSEC
    # the errors are consistent with the reported covariances (χ² with 3 degrees of freedom: mean 3)
    nees = np.array(
        [
            error_vector(r.attitude.matrix, f.attitude)
            @ np.linalg.solve(r.attitude.covariance, error_vector(r.attitude.matrix, f.attitude))
            for r, f in zip(results, frames)
        ]
    )
    assert nees.max() < 30.0 and 1.5 < nees[20:].mean() < 4.5


def test_the_jpdaf_filters_the_centroid_noise_that_sna_passes_on(sky, drift):
    truth, frames = drift
    rms = {}
    for tracker in ("sna", "jpdaf"):
        errors = check(run(sky, truth, frames, tracker=tracker, solver="wahba", sigma_a=0.05), frames)
        rms[tracker] = np.sqrt(np.mean(errors[30:] ** 2))
    assert rms["jpdaf"] < 0.7 * rms["sna"]


def test_stars_entering_the_field_are_identified_from_the_attitude_without_a_new_solve(sky):
    truth, frames = sequence(sky, "zenith", 0.0, n=120, period_s=600.0)  # 30 px/s: the field turns over
    for tracker in ("sna", "jpdaf"):
        results = run(sky, truth, frames, tracker=tracker)
        check(results, frames)
        first = set(results[0].star_ids.tolist())
        last = set(results[-1].star_ids.tolist())
        assert len(last - first) > 10 and len(last) > 20


def test_the_turn_model_without_rate_aid_follows_a_sky_rotating_about_the_boresight(sky):
    truth, frames = sequence(sky, "normal", 0.0, n=120, period_s=600.0)  # 0.6 °/s about the boresight
    results = run(sky, truth, frames, tracker="jpdaf", motion="coordinated_turn", aid="none", sigma_a=0.5)
    check(results, frames)


@pytest.mark.parametrize("boresight, motion", [("zenith", "constant_velocity"), ("normal", "coordinated_turn")])
def test_the_papers_jpdaf_with_the_jitter_compensated_tracks_both_motions(sky, boresight, motion):
    truth, frames = sequence(sky, boresight, 0.5, n=120, period_s=1200.0)
    results = run(sky, truth, frames, tracker="jpdaf", motion=motion, aid="jitter", sigma_a=0.05)
    errors = check(results, frames)
    sna = check(run(sky, truth, frames, tracker="sna"), frames)
    assert np.sqrt(np.mean(errors[30:] ** 2)) < np.sqrt(np.mean(sna[30:] ** 2))
    # without the compensation the jitter steps (10 frames each) throw the model off
    bare = run(sky, truth, frames, tracker="jpdaf", motion=motion, aid="none", sigma_a=0.05)
    bare_errors = [error_angle(r.attitude.matrix, f.attitude) for r, f in zip(bare, frames) if r.ok]
    assert sum(r.mode == "lost_in_space" for r in bare) > 2 or np.sqrt(np.mean(np.square(bare_errors))) > 2 * np.sqrt(
        np.mean(errors**2)
    )


@pytest.mark.parametrize("aid", ["rate", "jitter"])
def test_a_strong_jitter_compensated_from_the_first_frame_leaves_no_lag(sky, aid):
    """10× the paper's jitter: the compensation starts with the tracks (a filter started with the jitter in its
    velocities and compensated again would lag, and the bias check would have to restart it)."""
    truth, frames = sequence(sky, "normal", 5.0, n=60)
    catalogue, identifier = sky
    pipe = StarTrackerPipeline(
        catalogue,
        DEFAULT_CAMERA,
        SIGMA,
        tracker="jpdaf",
        motion="coordinated_turn",
        aid=aid,
        identifier=identifier,
        clutter_density=2.0 / 1024**2,
    )
    nees, errors = [], []
    for k, frame in enumerate(frames):
        j = max(k - 1, 0)
        r = pipe.process(frame.uv, frame.magnitudes, truth.t[k], truth.rate[j], truth.jitter_rate[j])
        assert r.ok
        e = error_vector(r.attitude.matrix, frame.attitude)
        nees.append(e @ np.linalg.solve(r.attitude.covariance, e))
        errors.append(np.linalg.norm(e))
    assert pipe.filter_resets == 0 and max(nees) < 30.0
    assert max(errors) < 15 * ARCSEC  # σ = 0.05 px over ~60 stars: a few arcsec, from the first frame on


def test_an_empty_frame_gives_no_attitude_and_the_next_one_reacquires(sky, drift):
    truth, frames = drift
    frames = list(frames[:20])
    empty = frames[10]
    frames[10] = type(empty)(np.empty((0, 2)), np.empty(0), np.empty(0, dtype=np.int64), empty.attitude)
    results = run(sky, truth, frames, tracker="jpdaf")
    assert not results[10].ok and results[10].attitude is None and "lock lost" in results[10].reason
    assert results[11].ok and results[11].mode == "lost_in_space"
    assert all(r.ok for k, r in enumerate(results) if k != 10)


def test_an_attitude_jump_the_rate_does_not_explain_falls_back_to_lost_in_space(sky, drift):
    truth, frames = drift
    catalogue = sky[0]
    rng = np.random.default_rng(5)
    jumped = Rotation.from_rotvec([0.0, 0.03, 0.02]).as_matrix() @ truth.attitude[15]  # 2° in one frame
    frames = list(frames[:25])
    frames[15] = simulate_frame(catalogue, DEFAULT_CAMERA, jumped, rng, sigma_px=SIGMA, n_false=2)
    for tracker in ("sna", "jpdaf"):
        results = run(sky, truth, frames, tracker=tracker)
        r = results[15]
        assert r.ok and r.mode == "lost_in_space"
        assert error_angle(r.attitude.matrix, jumped) < 10 * ARCSEC
        assert all(x.ok for x in results)


def test_a_burst_of_false_stars_never_gives_a_wrong_attitude(sky, drift):
    truth, frames = drift
    rng = np.random.default_rng(6)
    frames = list(frames[:20])
    for k in (8, 9):
        f = frames[k]
        junk = rng.uniform(0, 1024, (300, 2))
        frames[k] = type(f)(
            np.vstack([f.uv, junk]),
            np.concatenate([f.magnitudes, rng.uniform(2, 6, 300)]),
            np.concatenate([f.truth, -np.ones(300, dtype=np.int64)]),
            f.attitude,
        )
    for tracker in ("sna", "jpdaf"):
        results = run(sky, truth, frames, tracker=tracker)
        for r, f in zip(results, frames):
            if r.ok:
                ident = r.index >= 0
                np.testing.assert_array_equal(r.index[ident], f.truth[ident])
                assert error_angle(r.attitude.matrix, f.attitude) < 30 * ARCSEC
        assert results[-1].ok


def test_bad_options_are_refused(sky):
    with pytest.raises(ValueError):
        StarTrackerPipeline(sky[0], DEFAULT_CAMERA, SIGMA, tracker="kalman", identifier=sky[1])
    with pytest.raises(ValueError):
        StarTrackerPipeline(sky[0], DEFAULT_CAMERA, SIGMA, solver="quest", identifier=sky[1])
    with pytest.raises(ValueError):
        StarTrackerPipeline(sky[0], DEFAULT_CAMERA, SIGMA, motion="jerk", identifier=sky[1])
    with pytest.raises(ValueError):
        StarTrackerPipeline(sky[0], DEFAULT_CAMERA, SIGMA, min_stars=2, identifier=sky[1])


@pytest.mark.parametrize("tracker", ["sna", "jpdaf"])
def test_a_track_holding_the_wrong_star_is_caught_by_the_verification_and_dropped(sky, drift, tracker):
    truth, frames = drift
    catalogue, identifier = sky
    pipe = StarTrackerPipeline(
        catalogue, DEFAULT_CAMERA, SIGMA, tracker=tracker, identifier=identifier, clutter_density=2.0 / 1024**2
    )
    for k in range(5):
        assert pipe.process(frames[k].uv, frames[k].magnitudes, truth.t[k], truth.rate[max(k - 1, 0)]).ok
    wrong = int(np.setdiff1d(np.arange(len(catalogue)), pipe.tracker.ids)[0])  # a star not in view
    pipe.tracker.ids[0] = wrong  # a misidentified track
    r = pipe.process(frames[5].uv, frames[5].magnitudes, truth.t[5], truth.rate[4])
    assert r.ok and r.mode == "tracking"
    assert wrong not in r.index and wrong not in r.star_ids and wrong not in pipe.tracker.ids
    assert error_angle(r.attitude.matrix, frames[5].attitude) < 10 * ARCSEC
