"""SNA and JPDAF star tracking: JPDA weights against a hand-computed two-target case, the JPDAF as a Kalman
filter in the single-target clutter-free P_D = 1 case, clustering, and tracking a drifting star field."""

from __future__ import annotations

from math import exp, factorial, pi

import numpy as np
import pytest
from scipy.stats import chi2

from star_tracker.camera import DEFAULT_CAMERA
from star_tracker.jpdaf import JointProbabilisticAssociator, clusters, gate_volume
from star_tracker.motion import ConstantVelocity, CoordinatedTurn
from star_tracker.tracking import MISSED, JPDAFTracker, SNATracker, image_velocity, predict_centroids, sna_associate
from tracker_filters.association import gaussian_hypotheses

GATE = 4.0


def two_target_hypotheses():
    """Targets at (0, 0) and (2, 0), S = I; z0 = (1, 0) in both gates, z1 = (−0.5, 0.5) only in target 0's,
    z2 = (2.2, −0.3) only in target 1's (δ = 4)."""
    Z = np.array([[1.0, 0.0], [-0.5, 0.5], [2.2, -0.3]])
    return gaussian_hypotheses(
        np.array([[0.0, 0.0], [2.0, 0.0]]), np.full((2, 2, 2), 0.5 * np.eye(2)), Z, 0.5 * np.eye(2), chi2.cdf(GATE, 2)
    )


def by_hand(p_d, lam=None):
    """β written out event by event (d²: t0–z0 1, t0–z1 0.5, t1–z0 1, t1–z2 0.13; S = I so N = e^{−d²/2}/2π)."""
    p_g = 1.0 - exp(-GATE / 2.0)  # chi-square cdf with 2 dof
    N = {
        (0, 0): exp(-0.5) / (2 * pi),
        (0, 1): exp(-0.25) / (2 * pi),
        (1, 0): exp(-0.5) / (2 * pi),
        (1, 2): exp(-0.065) / (2 * pi),
    }
    miss = 1.0 - p_d * p_g
    V = 2 * pi * GATE  # two gates of c_2 δ |S|^½ = π · 4 · 1

    def clutter(phi):
        return lam**phi if lam is not None else factorial(phi) / V**phi

    events = {  # (detection of target 0, detection of target 1): weight; −1 = missed
        (-1, -1): miss * miss * clutter(3),
        (-1, 0): miss * p_d * N[1, 0] * clutter(2),
        (-1, 2): miss * p_d * N[1, 2] * clutter(2),
        (0, -1): p_d * N[0, 0] * miss * clutter(2),
        (0, 2): p_d * N[0, 0] * p_d * N[1, 2] * clutter(1),
        (1, -1): p_d * N[0, 1] * miss * clutter(2),
        (1, 0): p_d * N[0, 1] * p_d * N[1, 0] * clutter(1),
        (1, 2): p_d * N[0, 1] * p_d * N[1, 2] * clutter(1),
    }
    total = sum(events.values())
    beta = np.zeros((2, 4))
    for (a, b), w in events.items():
        beta[0, a + 1] += w / total
        beta[1, b + 1] += w / total
    return beta


@pytest.mark.parametrize("p_d, lam", [(0.9, 0.02), (0.6, 0.2), (0.95, None), (0.7, None)])
def test_jpda_weights_equal_the_hand_computed_two_target_case(p_d, lam):
    hyp = two_target_hypotheses()
    assert hyp.gated.tolist() == [[True, True, False], [True, False, True]]
    assoc = JointProbabilisticAssociator(p_d, lam).associate(hyp)
    got = np.array([a.weights for a in assoc])
    np.testing.assert_allclose(got, by_hand(p_d, lam), rtol=1e-10)
    np.testing.assert_allclose(got.sum(axis=1), 1.0)


@pytest.mark.parametrize("lam", [0.05, None])
def test_single_target_weights_are_the_pda_ones_whichever_path_computes_them(lam):
    """One target, three gated detections: by hand, through the vectorised single-target path, and through
    the event enumeration of a cluster."""
    Z = np.array([[10.5, 10.0], [9.0, 10.8], [10.2, 8.9], [30.0, 30.0]])
    hyp = gaussian_hypotheses(np.array([[10.0, 10.0]]), np.eye(2)[None], Z, np.eye(2), 0.99)
    p_d, p_g = 0.8, 0.99
    S = 2.0 * np.eye(2)
    nu = Z[:3] - 10.0
    N = np.exp(-0.5 * np.einsum("ni,ij,nj->n", nu, np.linalg.inv(S), nu)) / (2 * pi * np.sqrt(np.linalg.det(S)))
    density = lam if lam is not None else 3 / gate_volume(S, chi2.ppf(0.99, 2))  # non-parametric: λ = m/V
    w = np.concatenate([[density * (1 - p_d * p_g)], p_d * N])
    want = np.concatenate([w / w.sum(), [0.0]])
    jpda = JointProbabilisticAssociator(p_d, lam)
    np.testing.assert_allclose(jpda.associate(hyp)[0].weights, want, rtol=1e-10)
    np.testing.assert_allclose(jpda._cluster(hyp, np.array([0]), np.array([0, 1, 2]))[0], want[:4], rtol=1e-10)


def test_singletons_and_a_shared_cluster_in_one_frame_get_their_own_weights():
    Z = np.array([[1.0, 0.0], [40.3, 39.8], [-0.5, 0.5], [2.2, -0.3]])
    hyp = gaussian_hypotheses(
        np.array([[0.0, 0.0], [40.0, 40.0], [2.0, 0.0]]),
        np.full((3, 2, 2), 0.5 * np.eye(2)),
        Z,
        0.5 * np.eye(2),
        chi2.cdf(GATE, 2),
    )
    got = np.array([a.weights for a in JointProbabilisticAssociator(0.9, 0.02).associate(hyp)])
    pair = by_hand(0.9, 0.02)  # columns: miss, z0, z1, z2 of the two-target case
    np.testing.assert_allclose(got[0, [0, 1, 3, 4]], pair[0], rtol=1e-10)
    np.testing.assert_allclose(got[2, [0, 1, 3, 4]], pair[1], rtol=1e-10)
    assert got[0, 2] == got[2, 2] == 0.0 and got[1, [1, 3, 4]].tolist() == [0.0, 0.0, 0.0]
    assert got[1, 2] > 0.9


@pytest.mark.parametrize("lam", [2e-3, None])
def test_the_singletons_weighed_together_equal_each_targets_own_enumeration(lam):
    """Separate targets with up to four detections each in their gates: the weights computed for all of them
    at once over the gated pairs are each target's own single-target enumeration (:meth:`_cluster`)."""
    rng = np.random.default_rng(7)
    zhat = np.column_stack([np.arange(12) * 50.0, np.zeros(12)])
    A = rng.normal(size=(12, 2, 2)) * 0.3
    Pzz = A @ A.transpose(0, 2, 1) + 0.2 * np.eye(2)
    Z = np.vstack([zhat[r] + rng.normal(0, 0.8, (r % 5, 2)) for r in range(12)] + [[[700.0, 300.0]]])
    hyp = gaussian_hypotheses(zhat, Pzz, Z, 0.3 * np.eye(2), 0.999)
    jpda = JointProbabilisticAssociator(0.9, lam)
    got = jpda.weights(hyp)
    assert jpda.largest_cluster == 1 and len({int(n) for n in hyp.gated.sum(axis=1)}) >= 4
    for r in range(12):
        own = np.flatnonzero(hyp.gated[r])
        want = np.zeros(len(Z) + 1)
        want[np.r_[0, own + 1]] = jpda._cluster(hyp, np.array([r]), own)[0] if len(own) else 1.0
        np.testing.assert_allclose(got[r], want, rtol=1e-12, atol=1e-300)


def test_the_update_over_the_gated_pairs_equals_the_sums_over_every_detection():
    """Steps 5–7 summed over the pairs with β > 0 only equal the dense sums over every detection (clutter
    near the stars, so that gates hold several detections and clusters share them)."""
    rng = np.random.default_rng(8)
    tracker = JPDAFTracker(ConstantVelocity(2.0), 0.5, p_detect=0.9, clutter_density=1e-3)
    uv = rng.uniform(100, 900, (15, 2))
    uv[1] = uv[0] + [1.0, 0.5]  # two stars sharing detections
    tracker.start(np.arange(15), uv, velocity=rng.normal(0, 1, (15, 2)), velocity_sigma=2.0)
    tracker.predict(0.1)
    x, P = tracker.x.copy(), tracker.P.copy()
    Z = np.vstack([uv + rng.normal(0, 0.5, (15, 2)), uv[:8] + rng.normal(0, 1.5, (8, 2))])
    step = tracker.update(Z)
    beta = step.weights
    assert (np.count_nonzero(beta[:, 1:], axis=1) >= 2).sum() >= 5
    nu = Z[None, :, :] - x[:, None, [0, 2]]
    nu_c = np.einsum("tn,tnd->td", beta[:, 1:], nu)
    spread = np.einsum("tn,tnd,tne->tde", beta[:, 1:], nu, nu) - np.einsum("td,te->tde", nu_c, nu_c)
    S = P[:, [0, 2]][:, :, [0, 2]] + 0.25 * np.eye(2)
    K = P[:, :, [0, 2]] @ np.linalg.inv(S)
    Kt = K.transpose(0, 2, 1)
    want_P = P - (1 - beta[:, 0])[:, None, None] * (K @ S @ Kt) + K @ spread @ Kt
    np.testing.assert_allclose(tracker.x, x + np.einsum("tij,tj->ti", K, nu_c), rtol=1e-12)
    np.testing.assert_allclose(tracker.P, 0.5 * (want_P + want_P.transpose(0, 2, 1)), rtol=1e-9, atol=1e-12)


def test_gate_volume_is_eq_11():
    S = np.array([[4.0, 1.0], [1.0, 2.0]])
    assert gate_volume(S, 9.0) == pytest.approx(pi * 9.0 * np.sqrt(7.0))
    assert gate_volume(np.eye(3) * 4.0, 1.0) == pytest.approx(4 * pi / 3 * 8.0)
    assert gate_volume(np.eye(1) * 4.0, 9.0) == pytest.approx(2.0 * 3.0 * 2.0)


def test_far_apart_targets_are_separate_clusters_with_single_target_weights():
    zhat, Pzz = np.array([[0.0, 0.0], [100.0, 0.0]]), np.full((2, 2, 2), np.eye(2))
    Z = np.array([[0.5, 0.2], [-0.8, 0.4], [100.3, 0.1], [50.0, 50.0]])
    hyp = gaussian_hypotheses(zhat, Pzz, Z, np.eye(2), 0.999)
    assert [(t.tolist(), d.tolist()) for t, d in clusters(hyp.gated)] == [([0], [0, 1]), ([1], [2])]
    joint = JointProbabilisticAssociator(0.9, 1e-3).associate(hyp)
    for r in range(2):
        alone = gaussian_hypotheses(zhat[r : r + 1], Pzz[r : r + 1], Z, np.eye(2), 0.999)
        np.testing.assert_allclose(
            joint[r].weights, JointProbabilisticAssociator(0.9, 1e-3).associate(alone)[0].weights
        )
    assert joint[0].weights[4] == 0.0 and joint[1].weights[1] == 0.0  # nothing from outside its gate


def test_a_cluster_too_large_to_enumerate_falls_back_to_single_target_weights():
    zhat, Pzz = np.array([[0.1 * r, 0.0] for r in range(8)]), np.full((8, 2, 2), np.eye(2))
    Z = np.array([[0.1 * j, 0.05] for j in range(8)])
    hyp = gaussian_hypotheses(zhat, Pzz, Z, 0.1 * np.eye(2), 0.999)
    jpda = JointProbabilisticAssociator(0.9, 1e-3, max_events=1000)
    assoc = jpda.associate(hyp)
    assert jpda.approximated == 1
    np.testing.assert_allclose([a.weights.sum() for a in assoc], 1.0)
    single = JointProbabilisticAssociator(0.9, 1e-3)
    for r in (0, 5):
        alone = gaussian_hypotheses(zhat[r : r + 1], Pzz[r : r + 1], Z, 0.1 * np.eye(2), 0.999)
        np.testing.assert_allclose(assoc[r].weights, single.associate(alone)[0].weights)


def test_the_jpdaf_with_one_target_no_clutter_and_certain_detection_is_a_kalman_filter():
    rng = np.random.default_rng(0)
    sigma, dt = 0.3, 0.1
    model = ConstantVelocity(2.0)
    F, Q = model.transition(dt)
    H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    R = sigma**2 * np.eye(2)
    truth = np.array([500.0, 12.0, 400.0, -7.0])
    tracker = JPDAFTracker(model, sigma, p_detect=1.0, clutter_density=0.0)
    z0 = H @ truth + rng.normal(0, sigma, 2)
    tracker.start([42], z0[None], velocity=np.array([[10.0, -5.0]]), velocity_sigma=3.0)
    x = np.array([z0[0], 10.0, z0[1], -5.0])
    P = np.diag([sigma**2, 9.0, sigma**2, 9.0])
    for _ in range(60):
        truth = F @ truth
        z = H @ truth + rng.normal(0, sigma, 2)
        step = tracker.step(z[None], dt)
        x, P = F @ x, F @ P @ F.T + Q  # the Kalman filter, Table 1
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        x, P = x + K @ (z - H @ x), P - K @ S @ K.T
        assert step.detection.tolist() == [0] and step.weights[0, 1] == pytest.approx(1.0, abs=1e-12)
        np.testing.assert_allclose(tracker.x[0], x, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(tracker.P[0], P, rtol=1e-8, atol=1e-12)


def test_a_miss_keeps_the_prediction_and_a_soft_update_adds_the_spread_of_innovations():
    tracker = JPDAFTracker(ConstantVelocity(1.0), 0.5, p_detect=0.9, clutter_density=0.01)
    tracker.start([1], np.array([[100.0, 100.0]]))
    tracker.predict(0.1)
    x_pred, P_pred = tracker.x.copy(), tracker.P.copy()
    tracker.update(np.empty((0, 2)))
    np.testing.assert_allclose(tracker.x, x_pred)
    np.testing.assert_allclose(tracker.P, P_pred)
    # two detections symmetric about the prediction: the combined innovation is zero, the spread is not
    tracker.predict(0.1)
    x_pred, P_pred = tracker.x.copy(), tracker.P.copy()
    zhat = x_pred[0, [0, 2]]
    step = tracker.update(np.array([zhat + [0.6, 0.0], zhat - [0.6, 0.0]]))
    w = step.weights[0]
    assert w[1] == pytest.approx(w[2]) and 0 < w[0] < 1
    np.testing.assert_allclose(tracker.x, x_pred, atol=1e-12)
    S = P_pred[0][np.ix_([0, 2], [0, 2])] + 0.25 * np.eye(2)
    K = P_pred[0][:, [0, 2]] @ np.linalg.inv(S)
    spread = (w[1] + w[2]) * np.diag([0.36, 0.0])
    expected = P_pred[0] - (1 - w[0]) * K @ S @ K.T + K @ spread @ K.T
    np.testing.assert_allclose(tracker.P[0], expected, rtol=1e-10)
    assert tracker.P[0][0, 0] > P_pred[0][0, 0] - (1 - w[0]) * (K @ S @ K.T)[0, 0]


def test_turning_the_image_turns_positions_velocities_and_covariances():
    tracker = JPDAFTracker(ConstantVelocity(1.0), 0.5)
    tracker.start([3, 4], np.array([[612.0, 512.0], [512.0, 400.0]]), velocity=np.array([[2.0, 0.0], [0.0, 1.0]]))
    tracker.P[0] = np.diag([4.0, 1.0, 0.25, 0.5])
    tracker.turn_image(np.pi / 2, np.array([512.0, 512.0]))
    np.testing.assert_allclose(tracker.positions, [[512.0, 612.0], [624.0, 512.0]], atol=1e-9)
    np.testing.assert_allclose(tracker.x[:, [1, 3]], [[0.0, 2.0], [-1.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(np.diag(tracker.P[0]), [0.25, 0.5, 4.0, 1.0], atol=1e-12)


def test_predicted_centroids_follow_a_rotation_about_the_boresight():
    uv = np.array([[700.0, 300.0], [100.0, 900.0], [512.0, 512.0]])
    w, dt = 0.05, 0.1
    got = predict_centroids(DEFAULT_CAMERA, uv, np.array([0.0, 0.0, w]), dt)
    a = -w * dt  # the sky turns opposite to the camera
    Rm = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    np.testing.assert_allclose(got, (uv - 512.0) @ Rm.T + 512.0, atol=1e-9)
    v = image_velocity(DEFAULT_CAMERA, uv, np.array([0.0, 0.0, w]))
    np.testing.assert_allclose(v, -w * np.column_stack([-(uv[:, 1] - 512), uv[:, 0] - 512]), rtol=1e-6, atol=1e-9)
    # a turn about camera y moves the image along x, by about f·ω·dt
    shift = predict_centroids(DEFAULT_CAMERA, uv[2:], np.array([0.0, 1e-3, 0.0]), 1.0) - 512.0
    assert shift[0, 0] == pytest.approx(-DEFAULT_CAMERA.focal_px * 1e-3, rel=1e-6) and abs(shift[0, 1]) < 1e-9


def test_sna_takes_the_nearest_measurement_inside_its_euclidean_gate():
    predicted = np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0]])
    Z = np.array([[0.5, 0.0], [0.2, 0.1], [10.0, 0.9], [14.0, 0.0], [21.5, 0.0]])
    radius = 3 * np.sqrt(2) * 0.3  # 1.27 px for σ = 0.3
    assert sna_associate(predicted, Z, radius).tolist() == [1, 2, MISSED]
    # one measurement between two stars goes to the nearer
    assert sna_associate(np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([[0.6, 0.0]]), 1.0).tolist() == [MISSED, 0]
    assert SNATracker(DEFAULT_CAMERA, 0.3).radius == pytest.approx(radius)


def drifting_field(rng, n_frames, sigma, clutter, p_d, dt=0.1):
    """Twelve stars drifting at a constant image velocity; per frame the detected ones with noise plus
    Poisson clutter over the image, in random order, with the truth index (−1 for clutter)."""
    start = rng.uniform(200, 800, (12, 2))
    vel = np.array([3.0, -2.0])
    frames = []
    for n in range(n_frames):
        truth = start + vel * dt * n
        seen = rng.random(12) < p_d
        z = truth[seen] + rng.normal(0, sigma, (int(seen.sum()), 2))
        k = rng.poisson(clutter * 1024 * 1024)
        Z = np.vstack([z, rng.uniform(0, 1024, (k, 2))])
        who = np.concatenate([np.flatnonzero(seen), -np.ones(k, int)])
        perm = rng.permutation(len(Z))
        frames.append((truth, Z[perm], who[perm]))
    return frames, vel


def test_the_jpdaf_tracks_a_drifting_field_through_clutter_and_filters_the_noise():
    rng = np.random.default_rng(3)
    sigma, dt = 0.5, 0.1
    frames, vel = drifting_field(rng, 150, sigma, clutter=2e-5, p_d=0.95)
    truth0, Z0, who0 = frames[0]
    tracker = JPDAFTracker(ConstantVelocity(0.5), sigma, p_detect=0.95, clutter_density=2e-5)
    seen = who0 >= 0
    tracker.start(who0[seen], Z0[seen], velocity=np.broadcast_to(vel, (int(seen.sum()), 2)), velocity_sigma=1.0)
    sna = SNATracker(DEFAULT_CAMERA, sigma, max_misses=5)
    sna.start(who0[seen], Z0[seen])
    err_jpdaf, err_sna, wrong = [], [], 0
    for truth, Z, who in frames[1:]:
        step = tracker.step(Z, dt)
        taken = step.detection >= 0
        wrong += int(np.sum(who[step.detection[taken]] != step.ids[taken]))
        err_jpdaf.append(tracker.positions - truth[tracker.ids])
        sna.step(Z, dt, np.zeros(3))
        err_sna.append(sna.uv - truth[sna.ids])
    rms_jpdaf = np.sqrt(np.mean(np.concatenate(err_jpdaf) ** 2))
    rms_sna = np.sqrt(np.mean(np.concatenate(err_sna) ** 2))
    assert len(tracker) == 12 and wrong == 0
    assert rms_jpdaf < 0.6 * sigma < rms_sna  # SNA passes the noise through (and lags: no velocity)


def test_the_turn_model_tracks_a_rotating_field():
    rng = np.random.default_rng(4)
    sigma, dt, w = 0.2, 0.1, 0.05
    c = np.array([512.0, 512.0])
    p0 = rng.uniform(-400, 400, (10, 2))

    def at(t):
        a = w * t
        return p0 @ np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]).T + c

    tracker = JPDAFTracker(CoordinatedTurn(w, 0.05), sigma, p_detect=1.0, clutter_density=1e-6)
    v0 = w * np.column_stack([-p0[:, 1], p0[:, 0]])
    tracker.start(np.arange(10), at(0.0) + rng.normal(0, sigma, (10, 2)), velocity=v0, velocity_sigma=0.5)
    errs = []
    for n in range(1, 200):
        truth = at(n * dt)
        tracker.step(truth + rng.normal(0, sigma, (10, 2)), dt)
        errs.append(tracker.positions - truth[tracker.ids])
    assert len(tracker) == 10
    assert np.sqrt(np.mean(np.concatenate(errs[50:]) ** 2)) < 0.6 * sigma
