"""orbit_sim.orbit_fit: the batch least-squares orbit fit behind grace_velocity's dynamic estimator."""
import numpy as np
import pytest
from scipy.stats import chi2

from orbit_sim import kepler
from orbit_sim.constants import J2_EARTH, MU_EARTH
from orbit_sim.geopotential import ZONALS
from orbit_sim.orbit_fit import ForceModel, edges, fit_orbit, information, propagate

X0 = kepler.kepler_to_cartesian(6858137.0, 0.001, np.radians(89.0), 0.3, 0.2, 0.1, mu=MU_EARTH)
FULL = ForceModel(MU_EARTH, zonals={n: (J2_EARTH if n == 2 else ZONALS[n]) for n in range(2, 7)}, drag=True)
B_TRUE = 0.0045
T = np.arange(0.0, 3600.0 + 1.0, 10.0)
SIGMA = 0.02


def _truth(model=FULL, t=T):
    return propagate(X0, B_TRUE, np.zeros((1, 3)), model, t, edges(t[0], t[-1], None), with_partials=False).x


def test_noise_free_fixes_recover_the_orbit():
    truth = _truth()
    fit = fit_orbit(T, truth[:, :3], SIGMA, FULL, ballistic_guess=0.003)
    x, _ = fit.states(T, with_covariance=False)
    assert np.max(np.abs(x[:, :3] - truth[:, :3])) < 1e-3     # m
    assert np.max(np.abs(x[:, 3:] - truth[:, 3:])) < 1e-6     # m/s
    assert fit.residual_rms < 1e-3


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
    far closer to the truth than Savitzky-Golay's, and its covariance matches bound (b) at the truth."""
    from bench_engine.config import apply_overrides, load_scenario, select_variant
    from bench_eval.inprocess_runs import bag_data
    from bench_eval.scoring import run_offline, scoring_options
    from bench_studies.grace_velocity.bounds import dynamic_bound, range_rate_sd
    from bench_studies.grace_velocity.metrics import residuals

    cfg = apply_overrides(select_variant(load_scenario("grace_velocity"), "dynamic"),
                          ["time.duration=3600.0", "default_filters=[kf_a]"])
    data = bag_data(cfg, ["kf_a"], seed=3)
    opts = scoring_options(cfg)
    opts.offline = {k: v for k, v in opts.offline.items() if k in ("orbit_fit", "savgol")}
    run_offline(data, opts)
    rms = {n: np.sqrt(np.mean(residuals(data, n, opts.options)["truth"] ** 2)) for n in opts.offline}
    assert rms["orbit_fit"] < rms["savgol"] / 10
    t, bound = dynamic_bound(data)
    est = data.estimates["orbit_fit"]
    cols = [est.labels.index(c) for c in opts.options["baseline"]]
    own = range_rate_sd(est.x[:, cols[:3]], est.x[:, cols[3:]], est.P[:, cols][:, :, cols])
    assert np.allclose(own, bound[np.isin(t, est.t)], rtol=0.05)
