"""Numerical differentiation of sampled positions: paper 002's baseline and a stronger conventional one.

- ``newton_*``: the derivative of Newton's divided-difference interpolating polynomial of degree ``order``
  through order + 1 neighbouring samples (the paper's "Newton" method), evaluated at a sample. Centred
  windows inside a segment, one-sided at its ends; a window never spans a data gap longer than ``max_gap``.
  The derivative is linear in the samples, so it is a set of weights (``newton_weights``), which also
  propagates the samples' noise exactly.
- ``savgol_derivative``: Savitzky-Golay, the derivative of a least-squares polynomial of degree
  ``polyorder`` over ``window`` samples on each evenly sampled segment: centred inside, and at a segment's
  ends the derivative of the first or last window's polynomial at the end samples (scipy's ``interp`` ends).
  Its weights (``savgol_weights``) come from a QR solve in a Legendre basis over the window mapped onto
  [-1, 1], well conditioned for any window and degree; scipy.signal.savgol_coeffs solves the same least
  squares in powers of the unscaled sample index, an ill-conditioned Vandermonde matrix whose derivative weights
  lose their digits at high degree over long windows.

Both return NaN where a segment is too short to differentiate (a single isolated sample).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.polynomial import legendre


def divided_differences(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Newton's divided differences [y0], [y0 y1], ..., [y0 .. ym] of samples y (m+1, ...) at nodes t (m+1,).

    Column-wise on trailing dimensions: y may be (m+1,) or (m+1, d) or (m+1, k)."""
    t = np.asarray(t, dtype=float)
    c = np.array(y, dtype=float)
    for j in range(1, len(t)):
        c[j:] = (c[j:] - c[j - 1 : -1]) / (t[j:] - t[:-j]).reshape((-1,) + (1,) * (c.ndim - 1))
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


def savgol_weights(n: int, polyorder: int, at: np.ndarray) -> np.ndarray:
    """Weights W (len(at), n): row i gives p'(at_i) = sum_k W_ik y_k, p the least-squares polynomial of degree
    ``polyorder`` through samples y_k at the unit-spaced abscissae k = 0 .. n-1 (divide by the spacing for a
    derivative in time).

    The abscissae are mapped onto u in [-1, 1] and the polynomial written in Legendre polynomials, whose
    Vandermonde matrix V (n, polyorder + 1) is well conditioned on evenly spaced points; with V = QR the
    coefficients are R^-1 Q' y, so W = D R^-1 Q' with D the basis' derivatives at ``at`` (times du/dk)."""
    if not 1 <= polyorder < n:
        raise ValueError(f"Savitzky-Golay needs 1 <= polyorder < window, got {polyorder} and {n}")
    half = (n - 1) / 2.0
    q, r = np.linalg.qr(legendre.legvander((np.arange(n) - half) / half, polyorder))
    basis_slope = legendre.legder(np.eye(polyorder + 1), axis=0)  # (polyorder, polyorder + 1)
    D = legendre.legval((np.asarray(at, dtype=float) - half) / half, basis_slope).T / half
    return np.linalg.solve(r.T, D.T).T @ q.T


@lru_cache(maxsize=64)
def savgol_table(n: int, polyorder: int) -> np.ndarray:
    """``savgol_weights`` at every sample of an n-sample window (row (n - 1) / 2: the centred weights)."""
    w = savgol_weights(n, polyorder, np.arange(n))
    w.setflags(write=False)
    return w


def savgol_window_length(window_s: float, spacing: float, polyorder: int) -> int:
    """Samples of a Savitzky-Golay window of ``window_s`` seconds at ``spacing``: the largest odd number it
    holds, at least polyorder + 2 made odd, so the window keeps its length in time whatever the sampling."""
    n = int(window_s / spacing) + 1
    return max(n if n % 2 else n - 1, polyorder + 3 - polyorder % 2)


def savgol_derivative(
    t: np.ndarray, z: np.ndarray, window_length: int, polyorder: int, max_gap: float = np.inf
) -> np.ndarray:
    """Velocities (K, d) by Savitzky-Golay on each evenly sampled segment: centred windows inside, the first
    and last window's polynomial at the segment's ends.

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
            table = savgol_table(w, polyorder) / float(ts[1] - ts[0])
            h = w // 2
            out = v[seg]
            out[h : n - h] = np.einsum("k,i...k->i...", table[h], sliding_window_view(zs, w, axis=0))
            out[:h] = np.einsum("ik,k...->i...", table[:h], zs[:w])
            out[n - h :] = np.einsum("ik,k...->i...", table[w - h :], zs[n - w :])
            v[seg] = out
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
