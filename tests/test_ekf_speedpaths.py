"""The fast paths of the EKF step: the radar's shared-pass ``derivatives``, second-order moments over the
Hessians' non-zero block, the Joseph update's one-call Cholesky solve and the float conversion of the time.

Each is checked against the slower formulation it replaces (equal results) or against first principles."""

import numpy as np
import pytest

from bench_models.orbit_dynamics import OrbitJ2Dynamics
from bench_models.radar import GroundRadarModel
from orbit_sim.cowell import propagate
from orbit_sim.frames import ecef_to_eci, enu_rotation
from orbit_sim.kepler import kepler_to_cartesian
from tracker_filters.ekf import SecondOrderEKF, second_order_moments
from tracker_filters.kf import gain_and_nis, joseph_update

STATION = (np.radians(78.15306), np.radians(16.02889), 445.0)
THETA0 = np.radians(40.0)
CHAMP = kepler_to_cartesian(
    6739137.0, 0.00033, np.radians(87.2346), np.radians(303.3713), np.radians(81.5653), np.radians(80.0)
)


@pytest.fixture(params=[False, True], ids=["rae", "rae+rdot"])
def model(request):
    return GroundRadarModel(*STATION, theta0=THETA0, with_range_rate=request.param)


def states(model: GroundRadarModel, extra: int = 0) -> list[tuple[float, np.ndarray]]:
    """(t, state) pairs at spread look angles, azimuths next to north included; ``extra`` zero-Jacobian
    components appended to the six orbit ones."""
    rng = np.random.default_rng(11)
    out = []
    for t, rng_m, az, el in [
        (4400.0, 1.2e6, 1e-4, 0.3),
        (10.0, 9e5, 2 * np.pi - 1e-4, 0.6),
        (0.0, 2e6, 3.0, 0.09),
        (2500.0, 6e5, 4.5, 1.2),
    ]:
        u = rng_m * np.array([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])
        r = ecef_to_eci(model.station_ecef + enu_rotation(model.lat_rad, model.lon_rad).T @ u, t, model.theta0)
        out.append((t, np.concatenate((r, rng.normal(size=3) * 4.4e3, rng.normal(size=extra)))))
    return out


@pytest.mark.parametrize("extra", [0, 2])
def test_derivatives_equal_h_jacobian_and_hessian(model, extra):
    for t, x in states(model, extra):
        y, H, block = model.derivatives(x, t)
        m = 6 if model.with_range_rate else 3
        assert block.shape == (len(model.labels), m, m)
        np.testing.assert_array_equal(y, model.h(x, t))
        np.testing.assert_array_equal(H, model.jacobian(x, t))
        full = model.hessian(x, t)
        np.testing.assert_array_equal(block, full[:, 0:m, 0:m])
        assert not full[:, m:, :].any() and not full[:, :, m:].any()


def test_derivatives_match_central_differences_of_h(model):
    """The Jacobian and the Hessian block of ``derivatives`` against differences of its own h: second
    differences for the diagonal, mixed ones for the off-diagonal entries."""
    for t, x in states(model):
        y, H, block = model.derivatives(x, t)
        m = block.shape[-1]
        steps = np.array([1.0, 1.0, 1.0, 1e-2, 1e-2, 1e-2])

        def h(dx, x=x, t=t, y=y):
            return model.residual(model.derivatives(x + dx, t)[0], y)

        E = np.eye(6) * steps
        H_fd = np.column_stack([(h(E[k]) - h(-E[k])) / (2 * steps[k]) for k in range(6)])
        scale = np.abs(H_fd).max(axis=1, keepdims=True)
        np.testing.assert_allclose(H / scale, H_fd / scale, atol=1e-7)
        big = np.eye(6) * np.array([2e3, 2e3, 2e3, 20.0, 20.0, 20.0])  # the second-order terms dominate
        fd = np.empty_like(block)
        for j in range(m):
            for k in range(m):
                fd[:, j, k] = (h(big[j] + big[k]) - h(big[j] - big[k]) - h(big[k] - big[j]) + h(-big[j] - big[k])) / (
                    4 * big[j, j] * big[k, k]
                )
        scale = np.abs(fd).max(axis=(1, 2), keepdims=True)
        np.testing.assert_allclose(block / scale, fd / scale, atol=1e-3)  # measured 1.3e-4


def test_second_order_moments_of_a_block_equal_those_of_the_padded_hessians_and_the_traces():
    rng = np.random.default_rng(4)
    A = rng.normal(size=(6, 6))
    P = A @ A.T + np.eye(6)
    block = rng.normal(size=(4, 3, 3))
    block = block + block.transpose(0, 2, 1)
    padded = np.zeros((4, 6, 6))
    padded[:, 0:3, 0:3] = block
    bias, B = second_order_moments(block, P[0:3, 0:3])
    bias_full, B_full = second_order_moments(padded, P)
    np.testing.assert_allclose(bias, bias_full, rtol=1e-13)
    np.testing.assert_allclose(B, B_full, rtol=1e-13)
    np.testing.assert_allclose(bias, [0.5 * np.trace(Hi @ P[0:3, 0:3]) for Hi in block], rtol=1e-13)
    Pp = P[0:3, 0:3]
    np.testing.assert_allclose(B, [[0.5 * np.trace(Hi @ Pp @ Hj @ Pp) for Hj in block] for Hi in block], rtol=1e-13)


class RadarWithoutSharedPass(GroundRadarModel):
    """The radar as a model with only h, jacobian and hessian: the second-order EKF's fallback path."""

    derivatives = None


def test_second_order_ekf_gives_the_same_estimates_through_derivatives_and_the_three_calls(model):
    other = RadarWithoutSharedPass(*STATION, theta0=THETA0, with_range_rate=model.with_range_rate)
    times = 4330.0 + 0.1 * np.arange(31)
    truth = propagate(propagate(CHAMP, np.array([0.0, times[0]]))[-1], times)
    R = np.diag([1000.0, 0.017**2, 0.017**2, 1.0][0 : len(model.labels)])
    rng = np.random.default_rng(8)
    fast, slow = SecondOrderEKF(OrbitJ2Dynamics(0.0)), SecondOrderEKF(OrbitJ2Dynamics(0.0))
    for f in (fast, slow):
        f.initialise(
            truth[0] + np.array([2e3, -1e3, 1e3, 5.0, -5.0, 2.0]), np.diag([3e3**2] * 3 + [30.0**2] * 3), times[0]
        )
    for t, x in zip(times[1:], truth[1:]):
        z = model.h(x, t) + rng.normal(size=len(model.labels)) * np.sqrt(np.diag(R))
        nis_fast, nis_slow = fast.process(t, z, R, model).nis, slow.process(t, z, R, other).nis
        assert nis_fast == pytest.approx(nis_slow, rel=1e-9)
    np.testing.assert_allclose(fast.x, slow.x, rtol=1e-12)
    np.testing.assert_allclose(fast.P, slow.P, rtol=1e-9, atol=1e-12 * np.abs(slow.P).max())


def test_joseph_update_is_the_textbook_formula_and_a_non_positive_definite_s_is_refused():
    rng = np.random.default_rng(6)
    A = rng.normal(size=(6, 6))
    P = A @ A.T + np.eye(6)
    H = rng.normal(size=(3, 6))
    R = np.diag([2.0, 0.5, 1.0])
    x, nu = rng.normal(size=6), rng.normal(size=3)
    x_new, P_new, nis = joseph_update(x, P, nu, H, R)
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    I_KH = np.eye(6) - K @ H
    np.testing.assert_allclose(x_new, x + K @ nu, rtol=1e-12)
    np.testing.assert_allclose(P_new, I_KH @ P @ I_KH.T + K @ R @ K.T, rtol=1e-10, atol=1e-12)
    assert nis == pytest.approx(nu @ np.linalg.solve(S, nu), rel=1e-12)
    with pytest.raises(np.linalg.LinAlgError, match="Cholesky"):
        gain_and_nis(P @ H.T, np.diag([1.0, -1.0, 1.0]), nu)


def test_process_keeps_the_time_as_a_python_float():
    """A numpy scalar time (e.g. from an array of scan times) is stored as a float, so the next predict
    runs on Python floats; the value is unchanged."""
    model = GroundRadarModel(*STATION, theta0=THETA0)
    f = SecondOrderEKF(OrbitJ2Dynamics(0.0))
    x0 = propagate(CHAMP, np.array([0.0, 4330.0]))[-1]
    f.initialise(x0, np.diag([1e4] * 3 + [1.0] * 3), 4330.0)
    t = np.float64(4330.1)
    assert f.process(t, model.h(x0, 4330.1), np.diag([1000.0, 0.017**2, 0.017**2]), model).accepted
    assert type(f.t) is float and f.t == t
    f.predict(np.float64(4330.2))
    assert type(f.t) is float and f.t == 4330.2
