"""Vectorised batch re-solves: OrbitJ2Dynamics.trajectory, GroundRadarModel.h_series / jacobian_series and
PassBatch's vectorised linearisation against the per-scan loop (tracker_filters/relinearisation.py).

The filters' own re-solve tests (Kalman-filter equality, least-squares minimum) are in test_kf_ekf_ukf.py.
"""

import numpy as np
import pytest

from bench_models.orbit_dynamics import OrbitJ2Dynamics
from bench_models.radar import GroundRadarModel
from orbit_sim.cowell import propagate
from orbit_sim.kepler import kepler_to_cartesian
from tracker_filters.initialisation import initial_state_from_scan
from tracker_filters.relinearisation import PassBatch

CHAMP = kepler_to_cartesian(
    6739137.0, 0.00033, np.radians(87.2346), np.radians(303.3713), np.radians(81.5653), np.radians(80.0)
)
STATION = (np.radians(78.15306), np.radians(16.02889), 445.0)
THETA0 = np.radians(40.0)
PASS_START = 4321.0
"""s after the epoch of CHAMP: the start of its pass over STATION (scenario leo_radar)."""
R_RADAR = np.diag([1000.0, 0.017**2, 0.017**2])
R_DOPPLER = np.diag([400.0, 0.01**2, 0.01**2, 4.0])


def pass_start_state() -> np.ndarray:
    return propagate(CHAMP, np.array([0.0, PASS_START]))[-1]


def scan_times(seconds: float, seed: int) -> np.ndarray:
    """10 Hz scan times after PASS_START with 5 % missed (P_D = 0.95), irregular gaps."""
    rng = np.random.default_rng(seed)
    times = PASS_START + 0.1 * np.arange(1, round(seconds / 0.1) + 1)
    return times[rng.random(times.size) < 0.95]


def chain(dyn: OrbitJ2Dynamics, x0: np.ndarray, t0: float, times: np.ndarray):
    """States and Phi(t_j, t0) by the per-step path (propagate / transition_matrix from scan to scan)."""
    x, phi, t_prev, states, phis = x0, np.eye(6), t0, [], []
    for t in times:
        if t != t_prev:
            x, phi, t_prev = dyn.propagate(x, t - t_prev), dyn.transition_matrix(x, t - t_prev) @ phi, t
        states.append(x)
        phis.append(phi)
    return np.array(states), np.array(phis)


def assert_phi_close(phis: np.ndarray, ref: np.ndarray, rtol: float) -> None:
    """Each 3x3 block (dr/dr, dr/dv, dv/dr, dv/dv) to rtol of that block's largest entry."""
    for rows in (slice(0, 3), slice(3, 6)):
        for cols in (slice(0, 3), slice(3, 6)):
            scale = np.abs(ref[:, rows, cols]).max()
            np.testing.assert_allclose(phis[:, rows, cols], ref[:, rows, cols], rtol=0, atol=rtol * scale)


# ------------------------------------------------------------------------------------- dynamics


def test_trajectory_matches_the_per_step_chain_over_a_400_s_arc():
    dyn, x0 = OrbitJ2Dynamics(sigma_accel=0.0), pass_start_state()
    times = scan_times(400.0, seed=1)
    times = np.sort(np.concatenate((times, times[[10, 2000]], [PASS_START])))  # two sensors at once, t0
    states, phis = dyn.trajectory(x0, PASS_START, times)
    ref_states, ref_phis = chain(dyn, x0, PASS_START, times)
    assert states.shape == (times.size, 6) and phis.shape == (times.size, 6, 6)
    assert np.abs(states[:, 0:3] - ref_states[:, 0:3]).max() < 1e-3  # m
    assert np.abs(states[:, 3:6] - ref_states[:, 3:6]).max() < 1e-6  # m/s
    assert_phi_close(phis, ref_phis, rtol=1e-6)
    np.testing.assert_array_equal(phis[0], np.eye(6))  # the scan at t0
    # Phi over the whole arc is not close to the identity: the comparison above is not trivial
    assert np.abs(phis[-1, 0:3, 3:6]).max() > 300.0


def test_trajectory_handles_times_on_both_sides_of_t0_in_any_order():
    dyn, x0 = OrbitJ2Dynamics(sigma_accel=0.0), pass_start_state()
    offsets = np.array([30.0, -20.0, 0.0, -0.1, 30.0, 5.0])
    states, phis = dyn.trajectory(x0, PASS_START, PASS_START + offsets)
    for dt, x, phi in zip(offsets, states, phis):
        steps = PASS_START + np.sign(dt) * 0.1 * np.arange(round(abs(dt) / 0.1) + 1)  # backwards if dt < 0
        ref_x, ref_phi = chain(dyn, x0, PASS_START, steps)
        assert np.abs(x[0:3] - ref_x[-1, 0:3]).max() < 1e-4
        assert_phi_close(phi[None], ref_phi[-1:], rtol=1e-6)


# ------------------------------------------------------------------------------------ measurement


@pytest.mark.parametrize("with_range_rate", [False, True])
def test_series_methods_equal_looping_h_and_jacobian(with_range_rate):
    model = GroundRadarModel(*STATION, theta0=THETA0, with_range_rate=with_range_rate)
    dyn = OrbitJ2Dynamics(sigma_accel=0.0)
    times = scan_times(400.0, seed=2)[::7]
    states, _ = dyn.trajectory(pass_start_state(), PASS_START, times)
    states = np.column_stack((states, np.full(times.size, 3.0)))  # an extra state (e.g. a bias) is ignored
    h = model.h_series(states, times)
    H = model.jacobian_series(states, times)
    assert h.shape == (times.size, len(model.labels)) and H.shape == (times.size, len(model.labels), 7)
    h_ref = np.array([model.h(x, t) for x, t in zip(states, times)])
    H_ref = np.array([model.jacobian(x, t) for x, t in zip(states, times)])
    assert np.all(np.abs(h - h_ref) <= 1e-13 * np.abs(h_ref).max(axis=0))  # per component's scale
    np.testing.assert_allclose(H, H_ref, rtol=1e-11, atol=1e-12 * np.abs(H_ref).max())
    assert np.ptp(h[:, 1]) > 1.0 and np.all(H[:, :, 6] == 0.0)  # the azimuth sweeps; the bias column is 0


# ------------------------------------------------------------------------------------------ batch


def two_sensor_batch(vectorised: bool, seed: int = 4) -> tuple[PassBatch, np.ndarray, np.ndarray]:
    """40 s of the pass seen by two radars at the same site (one with range rate, several shared times;
    R changes half-way), first-scan prior: (batch, true state at t0, a guess 3 sigma off)."""
    rng = np.random.default_rng(seed)
    dyn = OrbitJ2Dynamics(sigma_accel=0.0)
    plain = GroundRadarModel(*STATION, theta0=THETA0)
    doppler = GroundRadarModel(*STATION, theta0=THETA0, with_range_rate=True)
    x0 = pass_start_state()
    z0 = plain.h(x0, PASS_START) + rng.normal(size=3) * np.sqrt(np.diag(R_RADAR))
    m0, P0 = initial_state_from_scan(z0, R_RADAR, plain, PASS_START, 8000.0)
    batch = PassBatch(dyn, m0, P0, PASS_START, vectorised=vectorised)
    t_plain, t_doppler = scan_times(40.0, seed), scan_times(40.0, seed + 1)[::5]
    scans = sorted(
        [(t, plain, R_RADAR * (1.0 if t < PASS_START + 20 else 2.0)) for t in t_plain]
        + [(t, doppler, R_DOPPLER) for t in t_doppler],
        key=lambda s: s[0],
    )
    states, _ = dyn.trajectory(x0, PASS_START, np.array([s[0] for s in scans]))
    for (t, model, R), x in zip(scans, states):
        z = model.h(x, t) + rng.multivariate_normal(np.zeros(R.shape[0]), R)
        z[1] = np.mod(z[1], 2 * np.pi)
        batch.add(t, z, R, model)
    guess = x0 + 3.0 * np.array([20.0, 20.0, 20.0, 1.0, 1.0, 1.0])
    return batch, x0, guess


def test_vectorised_and_per_scan_linearisations_agree():
    fast, x0, guess = two_sensor_batch(vectorised=True)
    slow, _, _ = two_sensor_batch(vectorised=False)
    assert len(fast._stack()[1]) == 2  # one group per measurement model
    for x in (x0, guess):
        a, b = fast.linearise(x), slow.linearise(x)
        assert a.cost == pytest.approx(b.cost, rel=1e-8)
        np.testing.assert_allclose(a.info, b.info, rtol=1e-8, atol=1e-8 * np.abs(b.info).max())
        np.testing.assert_allclose(a.gradient, b.gradient, rtol=1e-7, atol=1e-8 * np.abs(b.gradient).max())
        np.testing.assert_allclose(a.x_last, b.x_last, rtol=0, atol=1e-4)
        assert_phi_close(a.phi_last[None], b.phi_last[None], rtol=1e-7)
    x_fast, P_fast, _ = fast.solve(guess)
    x_slow, P_slow, _ = slow.solve(guess)
    e = x_fast - x_slow
    assert e @ np.linalg.solve(P_slow, e) < 1e-6
    np.testing.assert_allclose(P_fast, P_slow, rtol=1e-5, atol=1e-9)


def test_scans_added_after_a_linearisation_are_included():
    full, x0, _ = two_sensor_batch(vectorised=True)
    grown = PassBatch(full.dynamics, full.m0, np.linalg.inv(full.W0.T @ full.W0), full.t0)
    for n in (len(full) // 2, len(full)):
        for s in full.scans[len(grown) : n]:
            grown.add(s.t, s.z, np.linalg.inv(s.W.T @ s.W), s.model)
        lin = grown.linearise(x0)  # stacks the scans so far; the next pass must add the rest
    reference = full.linearise(x0)
    assert lin.cost == pytest.approx(reference.cost, rel=1e-10)
    np.testing.assert_allclose(lin.info, reference.info, rtol=1e-10)
    np.testing.assert_array_equal(lin.x_last, reference.x_last)


class WithoutSeries:
    """A measurement model without the batched methods: the radar's h / jacobian / residual only."""

    def __init__(self, model: GroundRadarModel) -> None:
        self.labels, self.angle_indices = model.labels, model.angle_indices
        self.h, self.jacobian, self.residual = model.h, model.jacobian, model.residual


def test_a_model_without_series_methods_falls_back_to_the_per_scan_loop(monkeypatch):
    batch, x0, _ = two_sensor_batch(vectorised=True)
    expected = batch.linearise(x0)
    last = batch.scans[-1]
    batch.add(last.t + 0.1, last.z, np.linalg.inv(last.W.T @ last.W), WithoutSeries(last.model))
    monkeypatch.setattr(OrbitJ2Dynamics, "trajectory", lambda *args: pytest.fail("vectorised path taken"))
    lin = batch.linearise(x0)
    assert lin.cost > expected.cost
    np.testing.assert_allclose(lin.x_last, batch.dynamics.propagate(expected.x_last, 0.1), atol=1e-6)
