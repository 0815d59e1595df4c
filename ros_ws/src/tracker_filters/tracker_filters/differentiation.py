"""Numerical differentiation of sampled positions: paper 002's baseline and a stronger conventional one.

- ``newton_*``: the derivative of Newton's divided-difference interpolating polynomial of degree ``order``
  through order + 1 neighbouring samples (the paper's "Newton" method), evaluated at a sample. Centred
  windows inside a segment, one-sided at its ends; a window never spans a data gap longer than ``max_gap``.
  The derivative is linear in the samples, so it is a set of weights (``newton_weights``), which also
  propagates the samples' noise exactly.
- ``savgol_derivative``: Savitzky-Golay, the derivative of a least-squares polynomial of degree
  ``polyorder`` over ``window`` samples (scipy.signal.savgol_filter on each evenly sampled segment).

Both return NaN where a segment is too short to differentiate (a single isolated sample).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.signal import savgol_filter


def divided_differences(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Newton's divided differences [y0], [y0 y1], ..., [y0 .. ym] of samples y (m+1, ...) at nodes t (m+1,).

    Column-wise on trailing dimensions: y may be (m+1,) or (m+1, d) or (m+1, k)."""
    t = np.asarray(t, dtype=float)
    c = np.array(y, dtype=float)
    for j in range(1, len(t)):
        c[j:] = (c[j:] - c[j - 1:-1]) / (t[j:] - t[:-j]).reshape((-1,) + (1,) * (c.ndim - 1))
    return c


def newton_polynomial_derivative(t: np.ndarray, coeffs: np.ndarray, t0: float) -> np.ndarray:
    """d/dt of p(t) = c0 + c1 (t - t0') + c2 (t - t0')(t - t1') + ... at t0, p built on nodes ``t``
    with divided-difference coefficients ``coeffs`` (Horner's scheme carrying the value and the slope)."""
    value = np.asarray(coeffs[-1], dtype=float) * 1.0
    slope = np.zeros_like(value)
    for j in range(len(t) - 2, -1, -1):
        slope = slope * (t0 - t[j]) + value
        value = value * (t0 - t[j]) + coeffs[j]
    return slope


def newton_weights(t: np.ndarray, t0: float) -> np.ndarray:
    """Weights w (m+1,) with p'(t0) = sum_k w_k y_k for Newton's polynomial through (t_k, y_k).

    Built by differentiating the Newton form of each unit sample (the polynomial is linear in y)."""
    t = np.asarray(t, dtype=float)
    return newton_polynomial_derivative(t, divided_differences(t, np.eye(len(t))), float(t0))


def weights_at_node(t: np.ndarray, at: int) -> np.ndarray:
    """``newton_weights`` of nodes t evaluated at node ``at``, cached by the nodes' offsets from the first
    (even sampling repeats the same few windows)."""
    return _relative_weights(tuple(np.round(np.asarray(t, dtype=float) - t[0], 9)), at)


@lru_cache(maxsize=256)
def _relative_weights(offsets: tuple[float, ...], at: int) -> np.ndarray:
    w = newton_weights(np.array(offsets), offsets[at])
    w.setflags(write=False)
    return w


def segments(t: np.ndarray, max_gap: float) -> list[slice]:
    """Runs of samples with no gap longer than ``max_gap`` between neighbours."""
    breaks = np.flatnonzero(np.diff(t) > max_gap) + 1
    edges = np.concatenate([[0], breaks, [len(t)]])
    return [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]


def window(i: int, n: int, size: int) -> tuple[int, int]:
    """[start, stop) of a window of ``size`` samples around index i of n: centred, shifted at the ends."""
    size = min(size, n)
    start = min(max(i - (size - 1) // 2, 0), n - size)
    return start, start + size


def newton_derivative(t: np.ndarray, z: np.ndarray, order: int, max_gap: float = np.inf) -> np.ndarray:
    """Velocities (K, d) of positions z (K, d) sampled at t (K,): Newton polynomials of degree ``order``
    (lower in segments shorter than order + 1 samples; NaN for a lone sample)."""
    t, z = np.asarray(t, dtype=float), np.asarray(z, dtype=float)
    if order < 1:
        raise ValueError(f"Newton differentiation needs order >= 1, got {order}")
    v = np.full_like(z, np.nan)
    for seg in segments(t, max_gap):
        ts, zs = t[seg], z[seg]
        n = len(ts)
        if n < 2:
            continue
        for i in range(n):
            a, b = window(i, n, order + 1)
            v[seg.start + i] = weights_at_node(ts[a:b], i - a) @ zs[a:b]
    return v


def savgol_derivative(t: np.ndarray, z: np.ndarray, window_length: int, polyorder: int,
                      max_gap: float = np.inf) -> np.ndarray:
    """Velocities (K, d) by Savitzky-Golay on each evenly sampled segment (scipy's ``interp`` ends).

    A segment shorter than the window uses the largest odd window it holds (at least polyorder + 2 samples);
    shorter still, Newton's polynomial through all of it."""
    t, z = np.asarray(t, dtype=float), np.asarray(z, dtype=float)
    if polyorder < 1 or window_length <= polyorder:
        raise ValueError(f"Savitzky-Golay needs 1 <= polyorder < window, got {polyorder} and {window_length}")
    v = np.full_like(z, np.nan)
    for seg in _even_segments(t, max_gap):
        ts, zs = t[seg], z[seg]
        n = len(ts)
        w = min(window_length, n if n % 2 else n - 1)
        if w >= polyorder + 2:
            v[seg] = savgol_filter(zs, w, polyorder, deriv=1, delta=float(ts[1] - ts[0]), axis=0, mode="interp")
        elif n >= 2:
            v[seg] = newton_derivative(ts, zs, n - 1)
    return v


def _even_segments(t: np.ndarray, max_gap: float) -> list[slice]:
    """Segments (no gap > max_gap) split further into runs of equal sample spacing (a sample where the
    spacing changes starts a new run)."""
    out = []
    for seg in segments(t, max_gap):
        a = seg.start
        for i in range(seg.start + 2, seg.stop):
            if i >= a + 2 and not np.isclose(t[i] - t[i - 1], t[a + 1] - t[a], rtol=1e-9, atol=1e-6):
                out.append(slice(a, i))
                a = i
        out.append(slice(a, seg.stop))
    return out
