"""tracker_filters.association.gaussian_hypotheses, the hypotheses of every (track, detection) pair at once that
MahalanobisHypothesiser and the star tracker's JPDAF share: against a pair-by-pair computation (scipy's
multivariate normal), with one noise covariance for all detections or one per detection, in 1 to 3 dimensions."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2, multivariate_normal

from tracker_filters.association import MahalanobisHypothesiser, MeasurementPrediction, gaussian_hypotheses


def random_case(rng, T, N, d, per_detection):
    z_pred = rng.uniform(-5, 5, (T, d))
    A = rng.normal(size=(T, d, d))
    Pzz = A @ A.transpose(0, 2, 1) + 0.1 * np.eye(d)
    Z = rng.uniform(-5, 5, (N, d))
    B = rng.normal(size=(N if per_detection else 1, d, d))
    R = B @ B.transpose(0, 2, 1) + 0.2 * np.eye(d)
    return z_pred, Pzz, Z, (R if per_detection else R[0])


@pytest.mark.parametrize("d", [1, 2, 3])
@pytest.mark.parametrize("per_detection", [False, True])
def test_every_pair_equals_its_own_gaussian(d, per_detection):
    rng = np.random.default_rng(10 * d + per_detection)
    z_pred, Pzz, Z, R = random_case(rng, 6, 9, d, per_detection)
    hyp = gaussian_hypotheses(z_pred, Pzz, Z, R, 0.99)
    assert hyp.d2.shape == hyp.log_likelihood.shape == (6, 9) and hyp.S.shape == (6, 9, d, d)
    for t in range(6):
        for n in range(9):
            S = Pzz[t] + (R[n] if per_detection else R)
            nu = Z[n] - z_pred[t]
            np.testing.assert_allclose(hyp.nu[t, n], nu, rtol=1e-14)
            np.testing.assert_allclose(hyp.S[t, n], S, rtol=1e-14)
            assert hyp.d2[t, n] == pytest.approx(nu @ np.linalg.solve(S, nu), rel=1e-10)
            assert hyp.log_likelihood[t, n] == pytest.approx(multivariate_normal(np.zeros(d), S).logpdf(nu), rel=1e-10)
    assert hyp.gate == pytest.approx(chi2.ppf(0.99, d)) and hyp.gate_probability == 0.99
    np.testing.assert_array_equal(hyp.gated, hyp.d2 <= hyp.gate)


def test_the_hypothesiser_is_the_same_computation_with_the_models_residual():
    """An angle measured across the wrap: the model's residual gives the small innovation."""

    class Bearing:
        def residual(self, z, z_pred):
            return np.mod(np.asarray(z) - np.asarray(z_pred) + np.pi, 2 * np.pi) - np.pi

    preds = [MeasurementPrediction(np.array([np.pi - 0.01]), np.array([[1e-4]]))]
    Z, R = np.array([[-np.pi + 0.01], [0.0]]), np.full((2, 1, 1), 1e-4)
    hyp = MahalanobisHypothesiser(0.99).hypothesise(preds, Z, R, Bearing())
    np.testing.assert_allclose(hyp.nu[0, :, 0], [0.02, -np.pi + 0.01], atol=1e-12)
    assert hyp.d2[0, 0] == pytest.approx(0.02**2 / 2e-4) and hyp.gated.tolist() == [[True, False]]
    same = gaussian_hypotheses(np.array([[np.pi - 0.01]]), np.array([[[1e-4]]]), Z, R, 0.99, Bearing().residual)
    np.testing.assert_array_equal(same.d2, hyp.d2)


def test_a_prediction_that_is_not_a_number_gates_nothing_and_no_detection_gives_empty_hypotheses():
    z_pred = np.array([[0.0, 0.0], [np.nan, 1.0]])
    Pzz = np.full((2, 2, 2), np.eye(2))
    hyp = gaussian_hypotheses(z_pred, Pzz, np.array([[0.1, 0.2], [5.0, 5.0]]), np.eye(2), 0.999)
    assert np.isinf(hyp.d2[1]).all() and (hyp.log_likelihood[1] == -np.inf).all()
    assert hyp.gated.tolist() == [[True, False], [False, False]]
    empty = gaussian_hypotheses(z_pred[:1], Pzz[:1], np.zeros((0, 2)), np.eye(2), 0.999)
    assert empty.d2.shape == (1, 0) and empty.nu.shape == (1, 0, 2) and empty.gate == np.inf
