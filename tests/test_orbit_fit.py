"""orbit_sim.orbit_fit: the batch least-squares orbit fit behind grace_velocity's dynamic estimator."""

import numpy as np
import pytest
from matplotlib.figure import Figure
from scipy.stats import chi2

from bench_engine.config import apply_overrides, load_scenario, select_variant
from bench_engine.settings import replaced
from bench_eval.inprocess_runs import bag_data
from bench_eval.scoring import run_offline, scoring_options
from bench_studies.grace_velocity.bounds import ORBIT_CRB
from bench_studies.grace_velocity.metrics import range_rate_bounds, range_rate_sd, residuals
from bench_studies.grace_velocity.report import _draw_residuals
from orbit_sim import kepler
from orbit_sim.constants import J2_EARTH, MU_EARTH
from orbit_sim.geopotential import (
    ZONALS,
    drag_acceleration,
    drag_acceleration_xyz,
    zonal_acceleration,
    zonal_acceleration_xyz,
)
from orbit_sim.gravity import gravity_gradient
from orbit_sim.orbit_fit import (
    ForceModel,
    _rate,
    edges,
    fit_orbit,
    information,
    normal_equations,
    position_change,
    propagate,
    rtn_frame,
    state_covariance,
)

X0 = kepler.kepler_to_cartesian(6858137.0, 0.001, np.radians(89.0), 0.3, 0.2, 0.1, mu=MU_EARTH)
FULL = ForceModel(MU_EARTH, zonals={n: (J2_EARTH if n == 2 else ZONALS[n]) for n in range(2, 7)}, drag=True)
B_TRUE = 0.0045
T = np.arange(0.0, 3600.0 + 1.0, 10.0)
SIGMA = 0.02


def _truth(model=FULL, t=T):
    return propagate(X0, B_TRUE, np.zeros((1, 3)), model, t, edges(t[0], t[-1], None), with_partials=False).x


EMPIRICAL = ForceModel(MU_EARTH, zonals={2: J2_EARTH}, drag=True, empirical_interval_s=600.0)
ARC = np.arange(0.0, 1800.0 + 1.0, 10.0)


def _p(x0: np.ndarray, ballistic: float, e: np.ndarray) -> np.ndarray:
    return np.concatenate([x0, [ballistic], e.ravel()])


def _dense_partials(traj) -> np.ndarray:
    """dx(t)/dp (K, 6, n) written out column by column: Phi for x0, s_drag for B; for e_j, Phi (W(t_j+1) - W(t_j))
    in intervals before t's, Phi (W(t) - W(t_j)) in t's own, zero after."""
    K, n_seg = len(traj.t), len(traj.W_edges) - 1
    H = np.zeros((K, 6, 7 + 3 * n_seg))
    H[:, :, :6], H[:, :, 6] = traj.phi, traj.s_drag
    for k in range(K):
        for j in range(traj.segment[k] + 1):
            upper = traj.W_edges[j + 1] if j < traj.segment[k] else traj.W[k]
            H[k, :, 7 + 3 * j : 10 + 3 * j] = traj.phi[k] @ (upper - traj.W_edges[j])
    return H


def test_the_single_state_forces_are_the_vectorised_ones():
    """The fit's right-hand side evaluates the forces on Python floats (orbit_sim.geopotential's *_xyz forms):
    the same arithmetic as the vectorised forms the truth integrates, equal to 1e-14 relative (a few ulp: numpy
    and libm round exp and a norm differently), over LEO states of every latitude."""
    rng = np.random.default_rng(5)
    for _ in range(300):
        r = rng.normal(size=3)
        r *= rng.uniform(6.55e6, 7.2e6) / np.linalg.norm(r)
        v = rng.normal(size=3) * 5e3
        expected = zonal_acceleration(r, MU_EARTH, FULL.re, FULL.zonals)
        np.testing.assert_allclose(
            zonal_acceleration_xyz(*r, MU_EARTH, FULL.re, FULL.zonals),
            expected,
            rtol=0,
            atol=1e-14 * np.linalg.norm(expected),
        )
        expected = drag_acceleration(r, v, B_TRUE, FULL.rotation_rate, FULL.re)
        np.testing.assert_allclose(
            drag_acceleration_xyz(*r, *v, B_TRUE, FULL.rotation_rate, FULL.re),
            expected,
            rtol=0,
            atol=1e-14 * np.linalg.norm(expected),
        )


def test_the_right_hand_side_is_the_variational_equations_written_out():
    """_rate's blocks against the variational equations with A = [[0, I], [G, 0]] formed in full (module
    docstring): Phi' = A Phi, Psi' = -Psi A, s' = A s + [0; a_drag], W' = Psi [0; R_rtn], the state's rate the
    forces plus R_rtn e."""
    rng = np.random.default_rng(6)
    for model, e in ((FULL, None), (EMPIRICAL, np.array([2e-7, -1e-7, 3e-7]))):
        y = np.concatenate([X0, rng.normal(size=96)])
        got = _rate(0.0, y, model, B_TRUE, e, True)
        r, v = y[:3], y[3:6]
        A = np.zeros((6, 6))
        A[:3, 3:] = np.eye(3)
        A[3:, :3] = gravity_gradient(*r, MU_EARTH, J2_EARTH, model.re)
        drag = drag_acceleration(r, v, 1.0, model.rotation_rate, model.re) if model.drag else np.zeros(3)
        rtn = rtn_frame(*y[:6])
        np.testing.assert_allclose(rtn.T @ rtn, np.eye(3), atol=1e-15)
        np.testing.assert_allclose(rtn[:, 0], r / np.linalg.norm(r), atol=1e-15)
        accel = (
            zonal_acceleration(r, MU_EARTH, model.re, model.zonals)
            + B_TRUE * drag
            + (rtn @ e if e is not None else 0.0)
        )
        phi, psi, s = y[6:42].reshape(6, 6), y[42:78].reshape(6, 6), y[78:84]
        expected = np.concatenate(
            [
                v,
                accel,
                (A @ phi).ravel(),
                (-psi @ A).ravel(),
                A @ s + np.concatenate([np.zeros(3), drag]),
                (psi[:, 3:] @ rtn).ravel(),
            ]
        )
        np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-13 * np.abs(expected).max())
        np.testing.assert_allclose(_rate(0.0, y[:6], model, B_TRUE, e, False), expected[:6], rtol=1e-14)


def test_the_variational_partials_match_finite_differences():
    """dx(t)/dp from the variational equations against central differences of the propagation, for the state,
    the ballistic coefficient and each interval's empirical acceleration (30 min, three 10-min intervals)."""
    t_edges = edges(ARC[0], ARC[-1], EMPIRICAL.empirical_interval_s)
    e = 1.0e-7 * np.arange(9.0).reshape(3, 3)
    traj = propagate(X0, B_TRUE, e, EMPIRICAL, ARC, t_edges)
    p0, partials = _p(X0, B_TRUE, e), _dense_partials(traj)
    steps = np.concatenate([[1.0] * 3, [1.0e-3] * 3, [1.0e-4], [1.0e-5] * 9])  # e: 16 m over 30 min
    for i, h in enumerate(steps):
        states = []
        for sign in (1.0, -1.0):
            p = p0.copy()
            p[i] += sign * h
            states.append(propagate(p[:6], p[6], p[7:].reshape(3, 3), EMPIRICAL, ARC, t_edges, with_partials=False).x)
        fd = (states[0] - states[1]) / (2 * h)
        analytic = partials[:, :, i]
        scale = np.max(np.abs(analytic), axis=0) + 1e-12
        # A holds the gradient of two-body + J2 only (module docstring): without drag's, dx/dB is off by about
        # 2e-3 of itself after 30 min, the cross-track empirical columns by 3e-4, the others by less
        tol = 1e-2 if i == 6 else 1e-3
        assert np.all(np.abs(fd - analytic) <= tol * scale), (i, np.max(np.abs(fd - analytic) / scale))


def test_interval_sums_equal_the_written_out_partials():
    """The normal equations, the position change and the state covariance summed interval by interval equal
    their dense forms with H = dx/dp written out."""
    t_edges = edges(ARC[0], ARC[-1], EMPIRICAL.empirical_interval_s)
    traj = propagate(X0, B_TRUE, np.zeros((3, 3)), EMPIRICAL, ARC, t_edges)
    H = _dense_partials(traj)
    n = H.shape[2]
    rng = np.random.default_rng(4)
    z = traj.x[:, :3] + SIGMA * rng.standard_normal((len(ARC), 3))
    N, b = normal_equations(traj, z, SIGMA, n, drag=True)
    Hr = H[:, :3].reshape(-1, n)
    assert np.allclose(N, Hr.T @ Hr / SIGMA**2, rtol=1e-10, atol=1e-12 * np.abs(N).max())
    assert np.allclose(b, Hr.T @ (z - traj.x[:, :3]).ravel() / SIGMA**2, rtol=1e-10, atol=1e-12 * np.abs(b).max())
    dp = rng.standard_normal(n) * np.concatenate([[1.0] * 6, [1e-4], [1e-7] * 9])
    assert np.allclose(position_change(traj, dp, drag=True), H[:, :3] @ dp, rtol=1e-10, atol=1e-9)
    A = rng.standard_normal((n, n))
    cov = A @ A.T * np.outer(np.abs(dp), np.abs(dp))
    P = state_covariance(traj, cov, drag=True)
    assert np.allclose(P, H @ cov @ H.transpose(0, 2, 1), rtol=1e-9, atol=1e-12 * np.abs(P).max())


def test_noise_free_fixes_recover_the_orbit():
    truth = _truth()
    fit = fit_orbit(T, truth[:, :3], SIGMA, FULL, ballistic_guess=0.003)
    x, _ = fit.states(T, with_covariance=False)
    assert np.max(np.abs(x[:, :3] - truth[:, :3])) < 1e-3  # m
    assert np.max(np.abs(x[:, 3:] - truth[:, 3:])) < 1e-6  # m/s
    assert fit.residual_rms < 1e-3


def test_the_reduced_dynamic_covariance_inverts_the_normal_matrix():
    """With empirical accelerations N is near singular in floating point (its condition number is checked to be
    above 1e15 over 3 h at 2 min): the covariance still inverts it to far better than a unit residual, and no state
    variance is negative. (An LU inverse, np.linalg.inv, misses the residual bound by orders of magnitude.)"""
    model = ForceModel(MU_EARTH, zonals={2: J2_EARTH}, empirical_interval_s=120.0)
    t = np.arange(0.0, 3 * 3600.0 + 1.0, 10.0)
    fit = information(model, X0, 0.0, t, SIGMA, empirical_sigma=1.0e-6)
    traj = propagate(X0, 0.0, fit.e, model, t, fit.t_edges)
    N, _ = normal_equations(traj, traj.x[:, :3], SIGMA, fit.n_params, drag=False)
    N[np.arange(6, fit.n_params), np.arange(6, fit.n_params)] += 1.0 / 1.0e-6**2
    assert np.linalg.cond(N) > 1e15
    assert np.abs(fit.covariance @ N - np.eye(fit.n_params)).max() < 1e-2
    assert np.array_equal(fit.covariance, fit.covariance.T)
    assert np.all(np.einsum("kii->ki", state_covariance(traj, fit.covariance, drag=False)) > 0)


def test_covariance_matches_the_monte_carlo_scatter():
    """The fit's covariance N^-1 against the scatter of the fitted epoch state over seeds (1 h arc)."""
    truth = _truth()
    errors = []
    for seed in range(8):
        z = truth[:, :3] + SIGMA * np.random.default_rng(seed).standard_normal((len(T), 3))
        fit = fit_orbit(T, z, SIGMA, FULL, ballistic_guess=B_TRUE)
        errors.append(np.concatenate([fit.x0 - X0, [fit.ballistic - B_TRUE]]))
    errors = np.array(errors)
    bound = information(FULL, X0, B_TRUE, T, SIGMA).covariance
    nees = np.einsum("ki,ij,kj->k", errors, np.linalg.inv(bound), errors)
    # 8 runs x 7 dof: the mean NEES is chi-square(56) / 8; its 99.9 % interval
    low, high = chi2.ppf([0.0005, 0.9995], 8 * 7) / 8
    assert low < np.mean(nees) < high
    # and the fit's own covariance is the bound at its estimate
    assert np.allclose(np.sqrt(np.diag(fit.covariance)), np.sqrt(np.diag(bound)), rtol=0.01)


def test_reduced_model_fits_worse_on_truth_data():
    """Fixes of the full-model truth (J2..J6, drag): a two-body + J2 model without drag leaves residuals well
    above the noise over two hours; the full model fits to the noise."""
    t = np.arange(0.0, 7200.0 + 1.0, 10.0)
    truth = _truth(t=t)
    z = truth[:, :3] + SIGMA * np.random.default_rng(1).standard_normal((len(t), 3))
    full = fit_orbit(t, z, SIGMA, FULL, ballistic_guess=0.004)
    reduced = fit_orbit(t, z, SIGMA, ForceModel(MU_EARTH, zonals={2: J2_EARTH}))
    assert full.residual_rms == pytest.approx(SIGMA, rel=0.05)
    assert reduced.residual_rms > 3 * SIGMA


def test_pair_orbit_fit_scores_in_grace_velocity():
    """The registered offline estimator on a short in-process grace_velocity run: its baseline range rate is
    far closer to the truth than Savitzky-Golay's, its covariance matches bound (b) at the truth, and the
    report's residual figure draws that bound (the metric's series carry it mapped to the range rate)."""

    cfg = apply_overrides(
        select_variant(load_scenario("grace_velocity"), "dynamic"),
        ["time.duration=3600.0", "scoring.window.head_s=600", "scoring.window.tail_s=600", "estimators=[kf_a]"],
    )
    data = bag_data(cfg, ["kf_a"], seed=3)
    opts = scoring_options(cfg)
    opts = replaced(opts, offline={k: v for k, v in opts.offline.items() if k in ("orbit_fit", "savgol")})
    run_offline(data, opts)
    rms = {n: np.sqrt(np.mean(residuals(data, n, opts.options)["truth"] ** 2)) for n in opts.offline}
    assert rms["orbit_fit"] < rms["savgol"] / 10
    # the fit estimates at every truth step (5 s), the others at the fixes (10 s): the scoring window keeps for
    # each the steps every one has (bench_eval.window)
    assert len(data.estimates["orbit_fit"].steps) > 1.9 * len(data.estimates["savgol"].steps)
    day, scored = opts.window.cut(data, ["kf_a", "orbit_fit", "savgol"])
    assert scored == ["kf_a", "orbit_fit", "savgol"]
    for name in scored:
        np.testing.assert_array_equal(day.estimates[name].steps, day.estimates["kf_a"].steps)
    data.bounds = {"orbit_crb": ORBIT_CRB.run(data, {})}
    bound = range_rate_bounds(data)["orbit_crb"]
    est = data.estimates["orbit_fit"]
    cols = [est.labels.index(c) for c in opts.options.baseline]
    own = range_rate_sd(est.x[:, cols[:3]], est.x[:, cols[3:]], est.P[:, cols][:, :, cols])
    t0 = min(t for t, _ in data.truth.values())
    assert np.allclose(own, bound["sd"][np.isin(bound["t"], est.t - t0)], rtol=0.05)
    fig = Figure()
    series = {**residuals(data, "orbit_fit", opts.options), "rr_bounds": {"orbit_crb": bound}}
    _draw_residuals({"orbit_fit": series})(fig)
    assert "√orbit_crb (vs truth)" in [line.get_label() for line in fig.axes[0].get_lines()]
