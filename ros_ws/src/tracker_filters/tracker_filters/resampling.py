"""Particle resampling schemes: each maps normalised weights (N,) to N ancestor indices.

All three are unbiased: the expected number of offspring of particle i is N·w_i. They differ in the
variance of that number (multinomial > residual, systematic; Douc & Cappé 2005). Vectorised with
``np.searchsorted`` on the cumulative weights, O(N log N).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

Resampler = Callable[[np.ndarray, np.random.Generator], np.ndarray]


def _validated(weights: np.ndarray) -> np.ndarray:
    """The weights as a float array; ValueError unless finite, non-negative, with a positive sum."""
    w = np.asarray(weights, dtype=float)
    if not (w.size and np.all(np.isfinite(w)) and np.all(w >= 0.0) and np.sum(w) > 0.0):
        raise ValueError("resampling needs finite, non-negative weights with a positive sum")
    return w


def _cumulative(weights: np.ndarray) -> np.ndarray:
    """Cumulative sum of the weights, normalised so that the last entry is exactly 1."""
    c = np.cumsum(_validated(weights))
    c /= c[-1]
    c[-1] = 1.0
    return c


def _pick(c: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Index i with c[i-1] <= u < c[i] for each u in [0, 1)."""
    return np.minimum(np.searchsorted(c, u, side="right"), c.size - 1)


def multinomial(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """N independent draws from the categorical distribution of the weights (paper 001, step 6)."""
    c = _cumulative(weights)
    return _pick(c, rng.random(c.size))


def systematic(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One uniform offset u0 ~ U[0, 1/N) and the comb u_k = u0 + k/N (Kitagawa 1996)."""
    c = _cumulative(weights)
    n = c.size
    return _pick(c, (rng.random() + np.arange(n)) / n)


def residual(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """floor(N·w_i) deterministic copies, the remaining R draws multinomial on the residual weights."""
    w = _validated(weights)
    n = w.size
    scaled = n * w / np.sum(w)
    copies = np.floor(scaled).astype(np.int64)
    deterministic = np.repeat(np.arange(n), copies)
    n_rest = n - deterministic.size
    if n_rest == 0:
        return deterministic
    c = _cumulative(scaled - copies)
    return np.concatenate([deterministic, _pick(c, rng.random(n_rest))])


RESAMPLERS: dict[str, Resampler] = {
    "multinomial": multinomial,
    "systematic": systematic,
    "residual": residual,
}
