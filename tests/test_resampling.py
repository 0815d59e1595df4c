"""Resampling schemes: unbiased offspring counts, variance ordering, edge cases."""

import numpy as np
import pytest

from tracker_filters.resampling import RESAMPLERS, multinomial, residual, systematic

N = 40
DRAWS = 4000


def offspring_counts(scheme, weights, draws, seed=0):
    """(draws, N) matrix: how many copies of each particle one resampling produced."""
    rng = np.random.default_rng(seed)
    n = weights.size
    return np.stack([np.bincount(scheme(weights, rng), minlength=n) for _ in range(draws)])


@pytest.fixture(scope="module")
def weights():
    w = np.random.default_rng(7).dirichlet(np.full(N, 0.7))
    w[3] = 0.0
    return w / w.sum()


@pytest.fixture(scope="module")
def counts(weights):
    return {name: offspring_counts(scheme, weights, DRAWS) for name, scheme in RESAMPLERS.items()}


@pytest.mark.parametrize("name", sorted(RESAMPLERS))
def test_expected_offspring_is_n_times_weight(name, weights, counts):
    c = counts[name]
    assert np.all(c.sum(axis=1) == N)
    standard_error = np.maximum(c.std(axis=0) / np.sqrt(DRAWS), 1.0 / DRAWS)
    z = (c.mean(axis=0) - N * weights) / standard_error
    assert np.max(np.abs(z)) < 5.0


@pytest.mark.parametrize("name", sorted(RESAMPLERS))
def test_zero_weight_particle_never_chosen(name, counts):
    assert np.all(counts[name][:, 3] == 0)


def test_systematic_and_residual_have_lower_variance_than_multinomial(counts):
    total_var = {name: c.var(axis=0).sum() for name, c in counts.items()}
    assert total_var["systematic"] < 0.5 * total_var["multinomial"]
    assert total_var["residual"] < 0.8 * total_var["multinomial"]


def test_systematic_count_is_floor_or_ceil_of_n_w(weights, counts):
    c = counts["systematic"]
    target = N * weights
    assert np.all(c >= np.floor(target) - 1e-9) and np.all(c <= np.ceil(target) + 1e-9)


def test_residual_keeps_the_deterministic_copies(weights, counts):
    assert np.all(counts["residual"] >= np.floor(N * weights)[None, :])


def test_uniform_weights_systematic_and_residual_keep_every_particle():
    w = np.full(10, 0.1)
    rng = np.random.default_rng(1)
    assert np.array_equal(np.sort(systematic(w, rng)), np.arange(10))
    assert np.array_equal(np.sort(residual(w, rng)), np.arange(10))


def test_single_dominant_particle_is_copied_n_times():
    w = np.zeros(25)
    w[11] = 1.0
    rng = np.random.default_rng(2)
    for scheme in (multinomial, systematic, residual):
        assert np.all(scheme(w, rng) == 11)


@pytest.mark.parametrize("name", sorted(RESAMPLERS))
@pytest.mark.parametrize(
    "bad", [np.zeros(5), np.array([0.2, np.nan, 0.3]), np.array([np.inf, 1.0]), np.array([0.5, -0.1, 0.6])]
)
def test_invalid_weights_raise(name, bad):
    with pytest.raises(ValueError):
        RESAMPLERS[name](bad, np.random.default_rng(0))
