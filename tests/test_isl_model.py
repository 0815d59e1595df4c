"""Inter-satellite-link measurement models (bench_models.isl): geometry, Jacobians, wrapping, batches."""

import numpy as np
import pytest

from bench_models.isl import RangeAzElModel, RelativePositionModel
from bench_models.models import MeasurementModel
from orbit_sim.relative import to_convention

CONVENTIONS = ("radial_along_normal", "along_radial")


def numerical_jacobian(model, x: np.ndarray, eps: float = 1e-4) -> np.ndarray:
    J = np.zeros((3, x.size))
    for k in range(x.size):
        dx = np.zeros_like(x)
        dx[k] = eps
        J[:, k] = model.residual(model.h(x + dx, 0.0), model.h(x - dx, 0.0)) / (2.0 * eps)
    return J


def test_models_satisfy_the_protocol():
    assert isinstance(RangeAzElModel(), MeasurementModel)
    assert isinstance(RelativePositionModel(), MeasurementModel)


@pytest.mark.parametrize("convention", CONVENTIONS)
@pytest.mark.parametrize("dim", [6, 9])
def test_range_az_el_jacobian_matches_finite_differences(convention, dim):
    rng = np.random.default_rng(3)
    model = RangeAzElModel(convention)
    for _ in range(20):
        x = rng.normal(size=dim) * 1000.0
        H = model.jacobian(x, 0.0)
        assert H.shape == (3, dim)
        assert np.allclose(H[:, 3:], 0.0)
        assert np.allclose(H, numerical_jacobian(model, x), rtol=1e-6, atol=1e-10)


def test_paper001_angles_are_measured_in_its_own_axes():
    """along_radial: alpha from the along-track axis towards radial, delta positive towards -normal."""
    m = RangeAzElModel("along_radial")
    assert np.allclose(m.h(np.array([0.0, 500.0, 0.0, 0, 0, 0])), [500.0, 0.0, 0.0])  # ahead
    assert np.allclose(m.h(np.array([500.0, 0.0, 0.0, 0, 0, 0])), [500.0, np.pi / 2, 0.0])  # above
    assert np.allclose(m.h(np.array([0.0, -500.0, 0.0, 0, 0, 0])), [500.0, np.pi, 0.0])  # behind
    assert np.allclose(m.h(np.array([0.0, 0.0, 500.0, 0, 0, 0]))[[0, 2]], [500.0, -np.pi / 2])  # +normal
    # eq. 6 with the state converted to the paper's axes (X, Y, Z) = (y, x, -z)
    x = np.array([500.0, 400.0, 200.0, 0.0, 0.0, 0.0])
    X, Y, Z = to_convention(x[0:3], "along_radial")
    rho = np.sqrt(X * X + Y * Y + Z * Z)
    assert np.allclose(m.h(x), [rho, np.arctan2(Y, X), np.arcsin(Z / rho)])


def test_paper004_angles_use_the_internal_axes():
    m = RangeAzElModel("radial_along_normal")
    assert np.allclose(m.h(np.array([300.0, 0.0, 0.0])), [300.0, 0.0, 0.0])
    assert np.allclose(m.h(np.array([0.0, 300.0, 0.0])), [300.0, np.pi / 2, 0.0])
    assert np.allclose(m.h(np.array([0.0, 0.0, 300.0]))[[0, 2]], [300.0, np.pi / 2])
    x = np.array([3.0, -4.0, 12.0])
    assert np.allclose(m.h(x), [13.0, 2.0 * np.pi + np.arctan2(-4.0, 3.0), np.arcsin(12.0 / 13.0)])


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_azimuth_range_and_wrapped_residual(convention):
    m = RangeAzElModel(convention)
    rng = np.random.default_rng(4)
    z = m.h(rng.normal(size=(200, 6)) * 1e3)
    assert np.all((z[:, 1] >= 0.0) & (z[:, 1] < 2.0 * np.pi))
    assert np.all(np.abs(z[:, 2]) <= np.pi / 2)
    r = m.residual(np.array([10.0, 0.001, 0.1]), np.array([9.0, 2.0 * np.pi - 0.001, 0.05]))
    assert np.allclose(r, [1.0, 0.002, 0.05])


def test_azimuth_is_continuous_through_the_wrap_for_filters():
    """A state just either side of alpha = 0: h jumps by 2 pi but the residual is the small angle."""
    m = RangeAzElModel("radial_along_normal")
    a = m.h(np.array([1000.0, -1e-3, 0.0]))
    b = m.h(np.array([1000.0, 1e-3, 0.0]))
    assert a[1] > 6.0 and b[1] < 0.1
    assert np.isclose(m.residual(b, a)[1], 2e-6)


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_batch_h_equals_row_by_row(convention):
    m = RangeAzElModel(convention)
    X = np.random.default_rng(5).normal(size=(7, 9)) * 500.0
    assert np.allclose(m.h(X, 0.0), np.array([m.h(x, 0.0) for x in X]))


def test_relative_position_model():
    m = RelativePositionModel()
    X = np.random.default_rng(6).normal(size=(4, 9))
    assert np.allclose(m.h(X), X[:, 0:3])
    assert np.allclose(m.h(X[1]), X[1, 0:3])
    H = m.jacobian(X[0], 0.0)
    assert H.shape == (3, 9)
    assert np.allclose(H @ X[2], X[2, 0:3])
    assert np.allclose(m.residual(np.array([7.0, 0.0, -7.0]), np.array([1.0, 6.0, 1.0])), [6.0, -6.0, -8.0])
