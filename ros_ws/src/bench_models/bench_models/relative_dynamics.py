"""Linear relative-motion dynamics models (paper 004, section 2) for any filter, in the internal LVLH axes.

State [x y z vx vy vz] (+ [bx by bz] for the bias model), x radial, y along-track, z orbit normal, in m
and m/s (``orbit_sim.relative`` converts to and from paper 001's axes). Every model here is linear and
time-invariant, x(t + T) = Phi(T) x(t) + w, so ``transition_matrix`` is Phi whatever the state, and Phi
and Q are cached per step T (the filters ask for them at every step, usually with the same T).

Process noise: continuous white-noise acceleration of spectral density sigma^2 [m^2/s^3] on each axis,
discretised per axis as sigma^2 [[T^3/3, T^2/2], [T^2/2, T]] (paper 004 eq. 38 prints T^3/2 in the
position-velocity entries: a typo, the integral gives T^2/2). This block neglects the CW coupling
inside the step (relative error O(n T) ~ 1e-3 at T = 1 s); the bias model uses the exact Van Loan integral.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from scipy.linalg import expm

from bench_engine.labels import BIAS, ORBIT
from bench_models.orbit_dynamics import white_acceleration_q
from orbit_sim.constants import J2_EARTH, MU_EARTH, R_EARTH
from orbit_sim.hill import cw_matrix

_CACHE_SIZE = 32
"""Steps T remembered per model (the oldest is dropped beyond that)."""


def wna_block(sigma: float | Sequence[float], dt: float) -> np.ndarray:
    """Discrete white-noise-acceleration Q (6, 6) over [x y z vx vy vz] for a step dt (|dt| is used).

    ``sigma`` is the per-axis spectral density root [m/s^(3/2)], a scalar or 3 values: the unit-PSD
    block of ``orbit_dynamics.white_acceleration_q`` scaled by sigma_axis^2 (it only couples an axis'
    position with its own velocity).
    """
    s = np.tile(np.broadcast_to(np.asarray(sigma, dtype=float), (3,)), 2)
    return white_acceleration_q(1.0, dt, 3) * np.outer(s, s)


def van_loan(A: np.ndarray, Qc: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretisation of dx = A x dt + dw, E[dw dw^T] = Qc dt: returns (Phi, Q) for the step dt.

    Van Loan (1978): expm([[-A, Qc], [0, A^T]] dt) = [[., Phi^-1 Q], [0, Phi^T]].
    """
    n = A.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -A
    M[:n, n:] = Qc
    M[n:, n:] = A.T
    E = expm(M * abs(float(dt)))
    Phi = E[n:, n:].T
    return Phi, Phi @ E[:n, n:]


class LinearRelativeDynamics:
    """Base of the LTI models: Phi = expm(A T) (or I + A T), Q = per-axis WNA block; both cached per T."""

    frame = "lvlh"

    def __init__(
        self, A: np.ndarray, labels: Sequence[str], sigma_accel: float | Sequence[float], discretisation: str = "exact"
    ) -> None:
        if discretisation not in ("exact", "euler"):
            raise ValueError(f"discretisation must be 'exact' or 'euler', got {discretisation!r}")
        self.A = np.array(A, dtype=float)
        self.A.setflags(write=False)
        self.labels = tuple(labels)
        self.sigma_accel = sigma_accel
        self.discretisation = discretisation
        self._phi_cache: dict[float, np.ndarray] = {}
        self._q_cache: dict[float, np.ndarray] = {}

    @staticmethod
    def _cached(cache: dict[float, np.ndarray], dt: float, make: Callable[[float], np.ndarray]) -> np.ndarray:
        key = float(dt)
        value = cache.get(key)
        if value is None:
            if len(cache) >= _CACHE_SIZE:
                cache.pop(next(iter(cache)))
            value = make(key)
            value.setflags(write=False)
            cache[key] = value
        return value

    def _make_phi(self, dt: float) -> np.ndarray:
        if self.discretisation == "euler":
            return np.eye(self.A.shape[0]) + self.A * dt
        return expm(self.A * dt)

    def _make_q(self, dt: float) -> np.ndarray:
        return wna_block(self.sigma_accel, dt)

    def transition_matrix(self, x: np.ndarray | None, dt: float) -> np.ndarray:
        """Phi(dt) (n, n), read-only; independent of x (the model is linear)."""
        return self._cached(self._phi_cache, dt, self._make_phi)

    def propagate(self, x: np.ndarray, dt: float) -> np.ndarray:
        """Phi x for one state (n,) or a batch (m, n)."""
        return np.asarray(x, dtype=float) @ self.transition_matrix(None, dt).T

    def process_noise(self, x: np.ndarray | None, dt: float) -> np.ndarray:
        """Discrete Q(dt) (n, n), read-only."""
        return self._cached(self._q_cache, dt, self._make_q)


class CWDynamics(LinearRelativeDynamics):
    """Clohessy-Wiltshire model (paper 004 sec. 2-1, eq. 4 in its standard, un-garbled form; paper 001 eq. 2).

    x'' - 2 n y' - 3 n^2 x = 0, y'' + 2 n x' = 0, z'' + n^2 z = 0, n [rad/s] the chief's mean motion.
    ``discretisation="exact"`` uses Phi = expm(A T) (the closed-form CW STM); ``"euler"`` is paper 001's
    Phi = I + T A (its section 1), kept to reproduce that paper as printed.
    """

    def __init__(self, n: float, sigma_accel: float | Sequence[float], discretisation: str = "exact") -> None:
        super().__init__(cw_matrix(n), ORBIT, sigma_accel, discretisation)
        self.n = float(n)


class CWBiasDynamics(LinearRelativeDynamics):
    """CW with a constant unknown acceleration beta (paper 004 sec. 2-2, eqs. 5-6), 9 states.

    r'' = CW(r, r') + beta, beta' = 0 + noise. Paper 004 writes "+ beta_i = 0" on the left-hand side,
    i.e. the opposite sign; beta is unknown and estimated, so only its sign convention differs.
    Phi = expm(A T) of the 9x9 A. Q is the exact (Van Loan) discretisation of white accelerations of
    density sigma_accel^2 on [vx vy vz] and white bias rates of density sigma_bias^2 [m^2/s^5] on
    [bx by bz]; with sigma_bias = 0 its position-velocity block equals ``wna_block`` to O(n T).
    """

    def __init__(self, n: float, sigma_accel: float | Sequence[float], sigma_bias: float | Sequence[float]) -> None:
        A = np.zeros((9, 9))
        A[0:6, 0:6] = cw_matrix(n)
        A[3:6, 6:9] = np.eye(3)
        super().__init__(A, ORBIT + BIAS, sigma_accel)
        self.n = float(n)
        self.sigma_bias = sigma_bias
        self._Qc = np.diag(
            np.concatenate(
                (
                    np.zeros(3),
                    np.broadcast_to(np.asarray(sigma_accel, dtype=float) ** 2, (3,)),
                    np.broadcast_to(np.asarray(sigma_bias, dtype=float) ** 2, (3,)),
                )
            )
        )

    def _make_q(self, dt: float) -> np.ndarray:
        return van_loan(self.A, self._Qc, dt)[1]


def ss_coefficients(
    a: float, inclination: float, mu: float = MU_EARTH, j2: float = J2_EARTH, re: float = R_EARTH
) -> dict[str, float]:
    """Schweighart-Sedwick constants for a reference orbit of radius a [m] and inclination [rad].

    Returns n = sqrt(mu / a^3), s = 3 J2 Re^2 / (8 a^2) (1 + 3 cos 2i), c = sqrt(1 + s) and
    q = k = n c + 3 n J2 Re^2 / (2 a^2) cos^2 i (see ``SchweighartSedwickDynamics``).
    """
    n = np.sqrt(mu / a**3)
    s = 3.0 * j2 * re**2 / (8.0 * a**2) * (1.0 + 3.0 * np.cos(2.0 * inclination))
    c = np.sqrt(1.0 + s)
    q = n * c + 1.5 * n * j2 * re**2 / a**2 * np.cos(inclination) ** 2
    return {"n": float(n), "s": float(s), "c": float(c), "q": float(q)}


class SchweighartSedwickDynamics(LinearRelativeDynamics):
    """Linearised J2 relative motion of Schweighart & Sedwick, "High-Fidelity Linearized J2 Model for
    Satellite Formation Flight", JGCD 25(6), 2002 (paper 004 sec. 2-3, eqs. 7-8, garbled there).

    Coefficients, as in the original:
      n = sqrt(mu / r_ref^3); s = 3 J2 Re^2 / (8 r_ref^2) (1 + 3 cos 2 i_ref); c = sqrt(1 + s)
      (paper 004 eq. 8 drops the 1/8; its cross-track line reads z'' - q^2 y, a typo for z'' + q^2 z);
      in-plane:   x'' - 2 (n c) y' - (5 c^2 - 2) n^2 x = 0,   y'' + 2 (n c) x' = 0.
    Its bounded in-plane motion needs vy = -2 n c x (CW: -2 n x); started where the osculating and mean
    orbits agree (argument of latitude 45 deg), the J2 truth drifts much less with SS's condition
    (tests/test_relative_dynamics.py).
    The original's right-hand sides (the -3 n^2 J2 Re^2/r_ref {...} sin^2(k t) terms of paper 004 eq. 7)
    are the J2 motion of ONE satellite about the reference orbit; they are the same for chief and deputy
    and cancel in the chief-deputy relative motion, which is why the homogeneous form is used here.
    Cross-track: the original gives z'' + q^2 z = 2 l q cos(q t + phi) with
      q = n c - (cos g0 sin g0 cot dW0 - sin^2 g0 cos i1)(W1' - W2') - W1' cos i1,
      Wj' = -3 n J2 Re^2 / (2 r_ref^2) cos ij (nodal rates), l ~ (W1' - W2'),
    which depends on the deputy's own differential inclination and node (g0, dW0). A time-invariant
    filter model cannot carry that, so the single-reference-orbit limit is used: deputy and chief share
    the inclination, W1' = W2', hence l = 0 and the bracket term vanishes, leaving the homogeneous
      z'' + q^2 z = 0,   q = n c - W' cos i = n c + 3 n J2 Re^2 / (2 r_ref^2) cos^2 i   (= the original's k).
    Checked against two-body + J2 truth (tests/test_relative_dynamics.py): for a formation whose
    cross-track motion comes from a node difference this q matches the true cross-track frequency to
    ~1e-5 relative (CW's n is off by ~8e-4 at i = 45 deg); a differential inclination makes the true
    cross-track amplitude grow (the l-forcing), which no homogeneous model represents.

    ``a`` is the reference-orbit radius: use the chief's MEAN orbital radius (its orbit-averaged |r|).
    For a chief started on an osculating circular orbit of a = 7100 km, the mean radius differs from a by
    -8 to +14 km depending on i and the starting argument of latitude (short-period J2 terms, amplitude
    ~1.5 J2 Re^2 / a sin^2 i); that shifts n by up to ~3e-3, more than the J2 corrections this model adds.
    With j2 = 0 the model is exactly CW.
    Provenance: the original paper was not available here; s, c, k, the in-plane coefficients and the
    q / l formulas above were cross-checked against several independent public re-implementations of
    SS 2002 (all agree), against paper 004 eqs. 7-8 (same structure, garbled constants) and numerically
    against two-body + J2 truth in tests/test_relative_dynamics.py.
    """

    def __init__(
        self,
        a: float,
        inclination: float,
        sigma_accel: float | Sequence[float],
        mu: float = MU_EARTH,
        j2: float = J2_EARTH,
        re: float = R_EARTH,
    ) -> None:
        k = ss_coefficients(a, inclination, mu, j2, re)
        n, c, q = k["n"], k["c"], k["q"]
        A = np.zeros((6, 6))
        A[0:3, 3:6] = np.eye(3)
        A[3, 0] = (5.0 * c * c - 2.0) * n * n
        A[3, 4] = 2.0 * n * c
        A[4, 3] = -2.0 * n * c
        A[5, 2] = -q * q
        super().__init__(A, ORBIT, sigma_accel)
        self.n, self.c, self.q, self.s = n, c, q, k["s"]
