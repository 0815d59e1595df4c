"""Particle filters: agreement with the Kalman filter on linear-Gaussian problems, degeneracy, recovery."""

import numpy as np
import pytest
from scipy.special import chdtri, logsumexp

from bench_engine.config import load_scenario
from bench_eval.inprocess_runs import bag_data
from bench_eval.metrics import nees_summary
from bench_eval.scoring import track_of
from bench_models.isl import RangeAzElModel
from bench_models.linear_models import ConstantVelocity, PositionMeasurement
from bench_models.relative_dynamics import CWDynamics
from orbit_sim.angles import wrap_angle, wrapped_residual
from orbit_sim.relative import from_convention
from tracker_filters.builders import build_filter_stack
from tracker_filters.kf import KalmanFilter
from tracker_filters.pf import RegularisedParticleFilter, SIRParticleFilter

FILTERS = (SIRParticleFilter, RegularisedParticleFilter)
DYN = ConstantVelocity(0.5, ndim=2)
MEAS = PositionMeasurement(ndim=2)
R = np.diag([1.0, 4.0])
X0 = np.array([0.0, 0.0, 1.0, -1.0])
P0 = np.diag([25.0, 25.0, 4.0, 4.0])


def run_against_kf(cls, n_particles, seed, times, R=R, P0=P0):
    """PF and KF on the same measurements; returns both filters (measurement times may skip steps)."""
    rng = np.random.default_rng(100)
    truth = X0 + rng.normal(size=4) * np.sqrt(np.diag(P0))
    pf, kf = cls(DYN, n_particles=n_particles, seed=seed), KalmanFilter(DYN)
    pf.initialise(X0, P0, 0.0)
    kf.initialise(X0, P0, 0.0)
    t_prev = 0.0
    for t in times:
        truth = DYN.propagate(truth, t - t_prev)
        t_prev = t
        z = MEAS.h(truth, t) + rng.normal(size=2) * np.sqrt(np.diag(R))
        assert pf.process(t, z, R, MEAS).accepted and kf.process(t, z, R, MEAS).accepted
    return pf, kf


@pytest.mark.parametrize("cls, mean_tol", [(SIRParticleFilter, 0.15), (RegularisedParticleFilter, 0.1)])
def test_linear_gaussian_moments_match_the_kalman_filter(cls, mean_tol):
    """Mean within mean_tol posterior sigma, variances within 12 %: Monte Carlo error at N = 20 000
    (measured over 12 seeds: worst mean error 0.085 (SIR) / 0.054 (pf) sigma, worst variance 5.6 %)."""
    times = [1.0, 2.0, 3.0, 5.0, 6.0, 7.0, 8.0, 10.0]
    pf, kf = run_against_kf(cls, 20_000, seed=4, times=times)
    sd = np.sqrt(np.diag(kf.P))
    assert np.all(np.abs(pf.x - kf.x) < mean_tol * sd)
    assert np.allclose(np.diag(pf.P), np.diag(kf.P), rtol=0.12)
    corr_pf = pf.P[0, 2] / np.sqrt(pf.P[0, 0] * pf.P[2, 2])
    corr_kf = kf.P[0, 2] / np.sqrt(kf.P[0, 0] * kf.P[2, 2])
    assert corr_pf == pytest.approx(corr_kf, abs=0.05)


@pytest.mark.parametrize("cls", FILTERS)
def test_uninformative_measurements_keep_the_predicted_moments(cls):
    """With R huge every update is a no-op, so the cloud must follow the KF prediction: the kernel
    regularisation of the "pf" must not inflate the covariance (Liu-West shrinkage); MC error ~1 %."""
    pf, kf = run_against_kf(cls, 20_000, seed=2, times=[1.0, 2.0, 3.0, 4.0, 5.0, 6.0], R=1e10 * np.eye(2))
    sd = np.sqrt(np.diag(kf.P))
    assert np.all(np.abs(pf.x - kf.x) < 0.05 * sd)
    assert np.all(np.abs(pf.P - kf.P) < 0.05 * np.outer(sd, sd))


def test_narrow_likelihood_degenerates_the_sir_but_not_the_pf():
    """Paper 001's regime: 50 m prior cloud, 2 cm measurement. The SIR keeps a handful of particles;
    the regularised PF with the linearised optimal proposal keeps > 5 % and still matches the KF."""
    P0_wide = np.diag([2500.0, 2500.0, 1.0, 1.0])
    R_narrow = np.diag([0.02**2, 0.02**2])
    n = 10_000
    sir, _ = run_against_kf(SIRParticleFilter, n, seed=1, times=[1.0], R=R_narrow, P0=P0_wide)
    pf, kf = run_against_kf(RegularisedParticleFilter, n, seed=1, times=[1.0], R=R_narrow, P0=P0_wide)
    assert sir.diagnostics()["n_eff"] < 10
    assert pf.diagnostics()["n_eff"] > 0.05 * n
    sd = np.sqrt(np.diag(kf.P))
    assert np.all(np.abs(pf.x - kf.x) < 0.2 * sd)
    assert np.allclose(np.diag(pf.P), np.diag(kf.P), rtol=0.2)
    assert np.all(np.abs(sir.x[:2] - kf.x[:2]) > 5 * sd[:2])


@pytest.mark.parametrize("cls", FILTERS)
def test_diagnostics_report_n_eff(cls):
    pf, _ = run_against_kf(cls, 500, seed=0, times=[1.0, 2.0])
    d = pf.diagnostics()
    assert 1.0 <= d["n_eff"] <= 500 and d["resampled"] in (0.0, 1.0)


def small_filter(cls, n=2000, seed=3):
    f = cls(DYN, n_particles=n, seed=seed)
    f.initialise(X0, P0, 0.0)
    return f


@pytest.mark.parametrize("cls", FILTERS)
def test_overflowing_likelihood_is_recovered_with_a_warning(cls):
    f = small_filter(cls)
    step = f.process(1.0, np.array([1e200, -1e200]), R, MEAS)
    assert step.accepted
    assert any("weight vanished" in w for w in step.warnings)
    assert np.all(np.isfinite(f.x)) and np.all(np.isfinite(f.P))
    assert np.allclose(f.x, DYN.propagate(X0, 1.0), atol=0.5 * np.sqrt(np.diag(P0)).max())
    assert np.all(np.isfinite(f.particles)) and f.weights.sum() == pytest.approx(1.0)
    assert f.process(2.0, MEAS.h(DYN.propagate(X0, 2.0), 2.0), R, MEAS).warnings == []


class NaNMeasurement:
    """Position measurement whose prediction is NaN wherever x < threshold."""

    labels = ("x", "y")
    angle_indices = ()

    def __init__(self, threshold):
        self.threshold = threshold

    def h(self, x, t):
        z = np.array(np.asarray(x, dtype=float)[..., 0:2])
        z[np.asarray(x)[..., 0] < self.threshold] = np.nan
        return z

    def jacobian(self, x, t):
        return np.eye(2, 4)

    def residual(self, z, z_pred):
        return np.asarray(z, dtype=float) - np.asarray(z_pred, dtype=float)


@pytest.mark.parametrize("cls", FILTERS)
def test_nan_likelihood_everywhere_is_recovered(cls):
    f = small_filter(cls)
    step = f.process(1.0, np.array([1.0, -1.0]), R, NaNMeasurement(threshold=np.inf))
    assert step.accepted and any("weight vanished" in w for w in step.warnings)
    assert np.all(np.isfinite(f.x)) and np.all(np.isfinite(f.P))


def test_nan_likelihood_on_part_of_the_cloud_zeroes_those_particles():
    f = small_filter(SIRParticleFilter, n=4000)
    step = f.process(1.0, np.array([3.0, -1.0]), R, NaNMeasurement(threshold=1.0))
    assert step.accepted and np.isfinite(step.nis)
    assert np.all(np.isfinite(f.x)) and f.x[0] > 1.0
    assert np.all(f.particles[f.weights > 0, 0] >= 1.0)


@pytest.mark.parametrize("cls", FILTERS)
def test_likelihood_far_below_exp_underflow_still_normalises(cls):
    """Every log-likelihood is < -1e4 (exp underflows to 0): logsumexp keeps a proper estimate."""
    f = small_filter(cls)
    z = np.array([200.0, -1.0])
    step = f.process(1.0, z, np.diag([0.01, 0.01]), MEAS)
    assert step.accepted and not any("weight vanished" in w for w in step.warnings)
    assert np.all(np.isfinite(f.x)) and f.x[0] > 10.0
    assert f.weights.sum() == pytest.approx(1.0)


class ExplodingDynamics(ConstantVelocity):
    """CV dynamics that sends particles with x < -3 to infinity."""

    def propagate(self, x, dt):
        out = super().propagate(x, dt)
        if out.ndim == 2:
            out[out[:, 0] < -3.0] = np.inf
        return out


@pytest.mark.parametrize("cls", FILTERS)
def test_particles_that_blow_up_in_propagation_get_zero_weight(cls):
    f = cls(ExplodingDynamics(0.5, ndim=2), n_particles=2000, seed=0)
    f.initialise(X0, P0, 0.0)
    step = f.process(1.0, np.array([1.0, -1.0]), R, MEAS)
    assert step.accepted and any("non-finite after propagation" in w for w in step.warnings)
    assert np.all(np.isfinite(f.x)) and np.all(np.isfinite(f.P))


@pytest.mark.parametrize("cls", FILTERS)
def test_rejected_or_failed_step_leaves_the_cloud_untouched(cls):
    f = small_filter(cls)
    f.process(1.0, np.array([1.0, -1.0]), R, MEAS)
    particles, weights, x = f.particles.copy(), f.weights.copy(), f.x.copy()
    assert not f.process(2.0, np.array([np.nan, 0.0]), R, MEAS).accepted
    failed = f.process(2.0, np.array([2.0, -2.0]), -np.eye(2), MEAS)
    assert not failed.accepted and "undone" in failed.reason
    assert np.array_equal(f.particles, particles) and np.array_equal(f.weights, weights)
    assert np.array_equal(f.x, x) and f.t == 1.0
    assert f.process(2.0, np.array([2.0, -2.0]), R, MEAS).accepted


def test_same_seed_same_result():
    a, _ = run_against_kf(RegularisedParticleFilter, 1000, seed=9, times=[1.0, 2.0, 3.0])
    b, _ = run_against_kf(RegularisedParticleFilter, 1000, seed=9, times=[1.0, 2.0, 3.0])
    assert np.array_equal(a.x, b.x) and np.array_equal(a.P, b.P)


@pytest.mark.parametrize("cls", FILTERS)
@pytest.mark.parametrize(
    "params",
    [{"n_particles": 1}, {"n_particles": 10.5}, {"resampling": "stratified?"}, {"threshold": 0.0}, {"threshold": 1.5}],
)
def test_invalid_parameters_raise(cls, params):
    with pytest.raises(ValueError):
        cls(DYN, **params)


@pytest.mark.parametrize("params", [{"bandwidth": 0.0}, {"bandwidth": 10.0}, {"iterations": -1}, {"iterations": 1.5}])
def test_invalid_pf_parameters_raise(params):
    with pytest.raises(ValueError):
        RegularisedParticleFilter(DYN, **params)


# --- paper 001's measurement model: exact weights, nonlinear posterior, azimuth wrap, consistency ---

PAPER_R = np.diag([0.02**2, np.radians(0.01) ** 2, np.radians(0.01) ** 2])
CW = CWDynamics(2.0 * np.pi / 7200.0, sigma_accel=1e-4)
RAE = RangeAzElModel("along_radial")


class RecordingRng:
    """A Generator that remembers its last standard-normal draw."""

    def __init__(self, rng):
        self.rng, self.last = rng, None

    def standard_normal(self, *args, **kwargs):
        self.last = self.rng.standard_normal(*args, **kwargs)
        return self.last

    def __getattr__(self, name):
        return getattr(self.rng, name)


@pytest.mark.parametrize("iterations, expect_passes", [(0, False), (3, True)])
def test_pf_log_weights_equal_the_direct_importance_ratio(iterations, expect_passes):
    """The factorised weights of the "pf" (3-row quadratic forms) equal log p(z|x) + log N(x; c, S) −
    log N(x; m', Σ) computed directly, with and without Gauss–Newton passes (50 m cloud, 2 cm range)."""
    f = RegularisedParticleFilter(CW, n_particles=4000, seed=7, threshold=1e-9, iterations=iterations)
    x0 = np.array([500.0, 400.0, -200.0, 0.0, 0.0, 0.0])
    f.initialise(x0, np.diag([50.0**2] * 3 + [1.0] * 3), 1.0)
    f._rng = RecordingRng(f._rng)
    before, x_bar, C = f.particles.copy(), f._cloud_mean.copy(), f._cloud_cov.copy()
    z = RAE.h(x0 + [20.0, -30.0, 10.0, 0.0, 0.0, 0.0])
    assert f.process(1.0, z, PAPER_R, RAE).accepted  # same time: no prediction, Q_pend = 0
    assert (f.diagnostics()["gn_passes"] > 0) == expect_passes and not f.diagnostics()["resampled"]
    a = np.sqrt(1.0 - f._h2)
    centres = a * before + (1.0 - a) * x_bar
    S = f._h2 * C
    d = f.particles - centres
    nu = RAE.residual(z, RAE.h(f.particles))
    direct = (
        -0.5 * np.einsum("ij,ij->i", nu, np.linalg.solve(PAPER_R, nu.T).T)
        - 0.5 * np.einsum("ij,ij->i", d, np.linalg.solve(S, d.T).T)
        + 0.5 * np.sum(f._rng.last**2, axis=0)
    )
    direct -= logsumexp(direct)
    assert np.all(np.isfinite(direct)) and np.ptp(direct) > 10.0
    np.testing.assert_allclose(f._logw, direct, rtol=1e-9, atol=1e-6)


def test_pf_matches_a_brute_force_posterior_on_a_curved_likelihood():
    """One update of a 50 m cloud with range/azimuth/elevation (2 m, 1°): the curvature asks for Gauss–Newton
    passes. Reference: 10⁶ prior samples weighted by the likelihood (N_eff ≈ 1 200; a second reference seed
    differs by 0.07 σ, 10 %). Measured over 6 seeds of the "pf": mean within 0.11 σ, variances within 13 %.
    The exact-weight test above is the sharp check; this one guards the whole update."""
    x0 = np.array([500.0, 400.0, -200.0, 0.0, 0.0, 0.0])
    P0 = np.diag([50.0**2] * 3 + [1.0] * 3)
    P0[0, 3] = P0[3, 0] = 30.0
    R_wide = np.diag([2.0**2, np.radians(1.0) ** 2, np.radians(1.0) ** 2])
    rng = np.random.default_rng(5)
    z = RAE.h(x0 + rng.normal(size=6) * np.sqrt(np.diag(P0))) + rng.normal(size=3) * np.sqrt(np.diag(R_wide))
    ref = SIRParticleFilter(CW, n_particles=1_000_000, seed=1, threshold=1e-9)
    pf = RegularisedParticleFilter(CW, n_particles=20_000, seed=0)
    for f in (ref, pf):
        f.initialise(x0, P0, 1.0)
        assert f.process(1.0, z, R_wide, RAE).accepted
    assert ref.diagnostics()["n_eff"] > 500 and pf.diagnostics()["gn_passes"] >= 1
    sd = np.sqrt(np.diag(ref.P))
    assert np.all(np.abs(pf.x - ref.x) < 0.2 * sd)
    np.testing.assert_allclose(np.diag(pf.P), np.diag(ref.P), rtol=0.2)


@pytest.mark.parametrize(
    "cls, R_meas", [(RegularisedParticleFilter, PAPER_R), (SIRParticleFilter, np.diag([0.5**2, 1e-3**2, 1e-3**2]))]
)
def test_azimuth_through_zero_gives_no_spike(cls, R_meas):
    """The deputy crosses the along-track axis (azimuth 2π → 0) at t = 20 s, the cloud straddling the wrap:
    no warning, bounded NIS and error at the crossing (an unwrapped 2π residual would vanish every weight)."""
    truth = np.array([20.0, 500.0, 5.0, -1.0, 0.0, 0.0])  # internal: radial 20 m -> 0 at t ≈ 20 s
    P0 = np.diag([0.3**2] * 3 + [0.01**2] * 3)
    rng = np.random.default_rng(3)
    f = cls(CW, n_particles=4000, seed=1)
    f.initialise(truth + rng.normal(size=6) * np.sqrt(np.diag(P0)), P0, 0.0)
    azimuths, errors, nis = [], [], []
    for k in range(1, 41):
        truth = CW.propagate(truth, 1.0)
        z = RAE.h(truth) + rng.normal(size=3) * np.sqrt(np.diag(R_meas))
        z[1] = np.mod(z[1], 2.0 * np.pi)
        step = f.process(float(k), z, R_meas, RAE)
        assert step.accepted and step.warnings == [], step.warnings
        azimuths.append(z[1])
        errors.append(np.linalg.norm(f.x[:3] - truth[:3]))
        nis.append(step.nis)
        if k == 20:
            straddle = np.ptp(RAE.h(f.particles)[:, 1])
    assert max(azimuths[:15]) < 0.1 and min(azimuths[25:]) > 6.0  # it did cross 0 going down
    assert straddle > 6.0  # the cloud itself was split across 0 / 2π at the crossing
    assert max(errors[10:]) < 3.0 * np.median(errors[10:]) + 0.05
    assert max(nis) < 40.0


def test_pf_is_consistent_on_paper_001_when_the_truth_follows_its_model():
    """formation_pf's filter (scenario config: CW, the paper's Q, P0, R), truth driven by the same Q:
    average NEES over 8 runs × 40 steps (after 20 s) close to the 6 dof (measured 6.2 at N = 2 000)."""

    cfg = load_scenario("formation_pf", ["filters.pf.params.n_particles=2000"])
    nees = []
    for run in range(8):
        stack = build_filter_stack(cfg, "pf")
        f, sensor, rng = stack.filter, stack.sensors["radio"], np.random.default_rng(run)
        x = from_convention(np.array([400.0, 500.0, 200.0, 0.0, 0.0, 0.0]), "along_radial")
        f.initialise(*stack.initialise(sensor.observe(x, 0.0, 0, rng), sensor.R, sensor, 0.0), 0.0)
        L_q = np.linalg.cholesky(f.dynamics.process_noise(x, 1.0))
        for k in range(1, 61):
            x = f.dynamics.propagate(x, 1.0) + L_q @ rng.standard_normal(6)
            assert f.process(float(k), sensor.observe(x, float(k), k, rng), sensor.R, sensor.model).accepted
            if k > 20:
                e = f.x - x
                nees.append(e @ np.linalg.solve(f.P, e))
    assert 4.5 < np.mean(nees) < 8.0


def test_wrap_angle_range_and_equivalence():
    a = np.array([np.pi, -np.pi, 3 * np.pi, -3 * np.pi, 0.0, 1e-300, -1e-300, 7.0, -7.0, 1e6])
    w = wrap_angle(a)
    assert np.all((w > -np.pi) & (w <= np.pi))
    np.testing.assert_array_equal(w[:4], np.pi)
    assert w[5] == 1e-300 and w[6] == -1e-300
    b = np.random.default_rng(0).uniform(-50.0, 50.0, 100_000)
    wb = wrap_angle(b)
    assert np.all((wb > -np.pi) & (wb <= np.pi))
    np.testing.assert_allclose(np.exp(1j * wb), np.exp(1j * b), atol=1e-13)
    np.testing.assert_allclose(
        wrapped_residual(np.zeros((2, 3)), np.full((2, 3), 2 * np.pi - 0.1), [1, 2]),
        [[-2 * np.pi + 0.1, 0.1, 0.1]] * 2,
        atol=1e-14,
    )


def test_the_papers_sir_is_not_consistent_on_formation_pf_and_the_bench_pf_is_conservative():
    """formation_pf as published (N = 10 000, 2 cm range, 0.01 deg angles, a noise-free CW truth), 60 s, five
    seeded runs in process (bench_engine.inprocess), scored by the bench's NEES code on the scorer's tracks.
    The study (docs/studies/formation_pf.md) measured: the paper's SIR collapses to one particle at the first update
    (N_eff = 1) and its NEES is ~1e39; the bench's pf is below the band (2.4: the filter assumes the paper's
    Q, the truth has no process noise). Asserted: the SIR's NEES is above the 95 % band by more than 1e6 and
    its N_eff is 1 at the median step; the pf's is below the band's lower limit, above a quarter of it."""

    cfg = load_scenario("formation_pf", ["time.duration=60"])
    runs = [bag_data(cfg, ["pf", "sir"], seed) for seed in range(1, 6)]
    sir = nees_summary([track_of(d, "sir") for d in runs], skip_s=10.0)
    pf = nees_summary([track_of(d, "pf") for d in runs], skip_s=10.0)
    lo, hi = sir["bounds"]
    assert sir["mean"] > 1e6 * hi and sir["fraction_inside"] == 0.0
    assert all(np.median(d.estimates["sir"].diagnostics["n_eff"]) < 1.5 for d in runs)
    assert lo / 4.0 < pf["mean"] < lo, f"pf NEES {pf['mean']:.2f}, band [{lo:.2f}, {hi:.2f}]"
    assert all(np.median(d.estimates["pf"].diagnostics["n_eff"]) > 500 for d in runs)


def test_the_sir_is_consistent_where_its_proposal_does_not_degenerate():
    """Where the transition prior is a workable proposal (2-D constant velocity, position measurements of
    1-2 m against a 5 m prior, the truth driven by the model's own Q), the SIR's NEES over 12 seeded runs of
    20 steps lies in the 95 % chi-square band of the 12-run average, chi2(4 N) / N, and is within 25 % of the
    Kalman filter's on the same data (the exact answer here)."""
    sir_nees, kf_nees = [], []
    for seed in range(12):
        rng = np.random.default_rng(seed)
        truth = X0 + rng.normal(size=4) * np.sqrt(np.diag(P0))
        sir, kf = SIRParticleFilter(DYN, n_particles=5000, seed=seed), KalmanFilter(DYN)
        sir.initialise(X0, P0, 0.0)
        kf.initialise(X0, P0, 0.0)
        L_q = np.linalg.cholesky(DYN.process_noise(truth, 1.0))
        for k in range(1, 21):
            truth = DYN.propagate(truth, 1.0) + L_q @ rng.standard_normal(4)
            z = MEAS.h(truth, float(k)) + rng.normal(size=2) * np.sqrt(np.diag(R))
            assert sir.process(float(k), z, R, MEAS).accepted and kf.process(float(k), z, R, MEAS).accepted
            for f, out in ((sir, sir_nees), (kf, kf_nees)):
                e = f.x - truth
                out.append(e @ np.linalg.solve(f.P, e))
    lo, hi = chdtri(4 * 12, np.array([0.975, 0.025])) / 12
    assert lo < np.mean(sir_nees) < hi, f"SIR NEES {np.mean(sir_nees):.2f} outside [{lo:.2f}, {hi:.2f}]"
    assert np.mean(sir_nees) == pytest.approx(np.mean(kf_nees), rel=0.25)
    assert 4.0 * np.mean(sir_nees) > hi and np.mean(sir_nees) / 4.0 < lo  # a factor 4 in P is outside
