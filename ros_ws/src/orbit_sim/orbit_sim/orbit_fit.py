"""Dynamic orbit determination: one satellite's orbit fitted to its GNSS position fixes by batch least squares.

The parameters p are the state x0 = [r0 v0] at the first fix, the ballistic coefficient B = C_d A / m when the
force model has drag, and, in the reduced-dynamic approach of GRACE orbit processing (Jaeggi et al. 2006,
J. Geodesy 80), piecewise-constant empirical accelerations e_j in the radial / along-track / cross-track
frame over intervals of ``empirical_interval_s``, each with the a-priori constraint e_j ~ N(0, sigma_e^2 I)
(the "weight" of the dynamics against the fixes). The force model is

    a(r, v) = a_zonal(r; J2..Jn) + B a_drag(r, v) + R_rtn(r, v) e_j        (orbit_sim.geopotential)

Gauss-Newton on the fixes z_k = r(t_k) + n_k, n_k ~ N(0, sigma^2 I), with the a-priori constraint:

    N = sum_k H_k' H_k / sigma^2 + Lambda_prior,   dp = N^-1 [sum_k H_k' (z_k - r(t_k)) / sigma^2 - Lambda_prior p]

H_k = d r(t_k) / d p from the variational equations (Montenbruck & Gill, "Satellite Orbits", section 7.2):
with A = [[0, I], [G, 0]], G = da/dr of the point mass and J2 (orbit_sim.gravity.gravity_gradient;
the partials of J3.. and of drag are below 1e-6 of these and are left out: they change the Jacobian, not the
converged fit), the state transition matrix
Phi(t) = d x(t) / d x0 obeys Phi' = A Phi, the drag sensitivity s' = A s + [0; a_drag]. The sensitivity to e_j
is Phi(t) [W(min(t, t_j+1)) - W(t_j)] for t > t_j, with W' = Phi^-1 [0; R_rtn]; Psi = Phi^-1 obeys
Psi' = -Psi A, so no inversion is needed. The covariance of p is N^-1 at convergence (the Fisher information
of the fixes plus the prior: with the truth's force model at the true p, the Cramer-Rao bound of the fit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import cho_factor, cho_solve, lapack

from orbit_sim.constants import OMEGA_EARTH, R_EARTH
from orbit_sim.geopotential import drag_acceleration, drag_acceleration_xyz, zonal_acceleration, zonal_acceleration_xyz
from orbit_sim.gravity import gravity_gradient

RTOL, ATOL = 1.0e-13, 1.0e-8
"""Tolerances as tight as those of a truth the fit is judged against: the integration error of the fitted
trajectory must stay well below the fit's own sigma, or it shows as inconsistency (NEES) that is not the fit's.
Even so the fit's trajectory is the less accurate of the two: solve_ivp's error norm is the RMS over all 102
components, and the partials, far inside their own tolerance, dilute the state's six."""
ATOL_PARTIALS = 1.0e-5
"""Absolute tolerance of the partials (their relative tolerance is RTOL): the trajectory sets the steps."""


@dataclass(frozen=True)
class ForceModel:
    """The fit's dynamics: zonal field {n: J_n} (n >= 2; empty: two-body), drag on or off, and the empirical
    accelerations' interval [s] (None: none)."""

    mu: float
    re: float = R_EARTH
    zonals: dict = field(default_factory=dict)
    drag: bool = False
    rotation_rate: float = OMEGA_EARTH
    empirical_interval_s: float | None = None

    def acceleration(self, r: np.ndarray, v: np.ndarray, ballistic: float) -> np.ndarray:
        """Gravity plus drag [m/s^2] at r, v (m, 3)."""
        a = zonal_acceleration(r, self.mu, self.re, self.zonals)
        if self.drag:
            a = a + drag_acceleration(r, v, ballistic, self.rotation_rate, self.re)
        return a


@dataclass
class Trajectory:
    """A propagated orbit and its partials at the times ``t``: state x (K, 6); Phi (K, 6, 6) = dx/dx0;
    s_drag (K, 6) = dx/dB; W (K, 6, 3) the empirical integral; ``segment`` (K,) the interval of each time;
    ``W_edges`` (J + 1, 6, 3) W at the intervals' edges.

    The partials dx(t)/dp are never formed (K x 6 x n_params, n_params = 2167 for a day at 2 min): they factor as
    dx(t)/dp = F(t) G(t), F = [Phi | s_drag] (6, nb), nb = 6 (+1 with drag), and G(t) = [I | dW_0 .. dW_s-1,
    V(t), 0 ..] with the intervals' steps dW_j = W(t_j+1) - W(t_j) and V(t) = W(t) - W(t_s) in the interval s
    of t (both padded with a zero row for B). Sums over the fixes then collapse to sums per interval."""

    t: np.ndarray
    x: np.ndarray
    phi: np.ndarray
    s_drag: np.ndarray
    W: np.ndarray
    segment: np.ndarray
    W_edges: np.ndarray

    def base(self, drag: bool) -> np.ndarray:
        """F (K, 6, nb) = dx(t)/d[x0 (, B)]."""
        return np.concatenate([self.phi, self.s_drag[:, :, None]], axis=2) if drag else self.phi

    def steps(self, nb: int) -> tuple[np.ndarray, np.ndarray]:
        """dW (J, nb, 3), the intervals' steps, and V (K, nb, 3), the step into each time's interval."""
        dW = np.zeros((self.W_edges.shape[0] - 1, nb, 3))
        dW[:, :6] = np.diff(self.W_edges, axis=0)
        V = np.zeros((len(self.t), nb, 3))
        V[:, :6] = self.W - self.W_edges[self.segment]
        return dW, V

    def per_interval(self, values: np.ndarray) -> np.ndarray:
        """Sums of ``values`` (K, ...) over the times of each interval (J, ...)."""
        out = np.zeros((self.W_edges.shape[0] - 1, *values.shape[1:]))
        np.add.at(out, self.segment, values)
        return out


def _sums_after(per_interval: np.ndarray) -> np.ndarray:
    """(J, ...): row j is the sum of the rows after j (the last row is zero)."""
    out = np.zeros_like(per_interval)
    out[:-1] = np.cumsum(per_interval[:0:-1], axis=0)[::-1]
    return out


def _rate(t: float, y: np.ndarray, model: ForceModel, ballistic: float, e: np.ndarray | None, with_partials: bool):
    """d/dt of [x, Phi, Psi, s_drag, W] (module docstring), or of x alone; ``e``: the interval's empirical
    acceleration (RTN), None for none. The forces on Python floats
    (orbit_sim.geopotential's single-state forms) and the partials by blocks of A = [[0, I], [G, 0]]
    (A Phi = [Phi_v; G Phi_r], -Psi A = -[Psi_v G, Psi_r]) rather than numpy calls on 3-vectors and full 6 x 6
    products: the same values to rounding (tests/test_orbit_fit.py), at a fraction of the cost of a call, which a
    day's fit makes about a hundred thousand times."""
    rx, ry, rz, vx, vy, vz = y[:6].tolist()
    ax, ay, az = zonal_acceleration_xyz(rx, ry, rz, model.mu, model.re, model.zonals)
    if model.drag:
        dx, dy, dz = drag_acceleration_xyz(rx, ry, rz, vx, vy, vz, 1.0, model.rotation_rate, model.re)
        ax, ay, az = ax + ballistic * dx, ay + ballistic * dy, az + ballistic * dz
    else:
        dx = dy = dz = 0.0
    rtn = rtn_frame(rx, ry, rz, vx, vy, vz) if with_partials or e is not None else None
    if e is not None:
        ex, ey, ez = (rtn @ e).tolist()
        ax, ay, az = ax + ex, ay + ey, az + ez
    out = np.empty(len(y))
    out[:6] = vx, vy, vz, ax, ay, az
    if not with_partials:
        return out
    G = gravity_gradient(rx, ry, rz, model.mu, model.zonals.get(2, 0.0), model.re)
    phi, psi = y[6:42].reshape(6, 6), y[42:78].reshape(6, 6)
    dphi, dpsi = out[6:42].reshape(6, 6), out[42:78].reshape(6, 6)
    dphi[:3], dphi[3:] = phi[3:], G @ phi[:3]
    dpsi[:, :3], dpsi[:, 3:] = -(psi[:, 3:] @ G), -psi[:, :3]
    s = y[78:84]
    out[78:81] = s[3:]
    out[81:84] = G @ s[:3] + (dx, dy, dz)
    out[84:] = (psi[:, 3:] @ rtn).ravel()
    return out


def rtn_frame(rx: float, ry: float, rz: float, vx: float, vy: float, vz: float) -> np.ndarray:
    """Columns: radial, along-track (completing the triad), cross-track (orbit normal) unit vectors (3, 3) of one
    state: the transpose of orbit_sim.relative.lvlh_basis, written out on floats because the fit's right-hand side
    calls it at every integrator stage."""
    rn = math.sqrt(rx * rx + ry * ry + rz * rz)
    hx, hy, hz = rx / rn, ry / rn, rz / rn
    nx, ny, nz = ry * vz - rz * vy, rz * vx - rx * vz, rx * vy - ry * vx
    nn = math.sqrt(nx * nx + ny * ny + nz * nz)
    nx, ny, nz = nx / nn, ny / nn, nz / nn
    return np.array([[hx, ny * hz - nz * hy, nx], [hy, nz * hx - nx * hz, ny], [hz, nx * hy - ny * hx, nz]])


def edges(t0: float, t1: float, interval: float | None) -> np.ndarray:
    """The empirical intervals' edges from t0 to t1 (the last interval absorbs a remainder shorter than half)."""
    if interval is None:
        return np.array([t0, t1])
    n = max(1, int(round((t1 - t0) / interval)))
    return np.linspace(t0, t1, n + 1)


def propagate(
    x0: np.ndarray,
    ballistic: float,
    e: np.ndarray,
    model: ForceModel,
    t: np.ndarray,
    t_edges: np.ndarray,
    with_partials: bool = True,
    rtol: float = RTOL,
) -> Trajectory:
    """The orbit from x0 at t_edges[0] to the times ``t`` (ascending, within the edges), interval by interval
    (the empirical accelerations ``e`` (J, 3) jump at the edges: each interval is integrated on its own)."""
    n_seg = len(t_edges) - 1
    y = (
        np.concatenate([x0, np.eye(6).ravel(), np.eye(6).ravel(), np.zeros(6), np.zeros(18)])
        if with_partials
        else np.asarray(x0, float)
    )
    atol = np.full(len(y), ATOL_PARTIALS)
    atol[:3], atol[3:6] = ATOL, ATOL * 1.0e-3
    seg = np.clip(np.searchsorted(t_edges, t, side="right") - 1, 0, n_seg - 1)
    out = np.empty((len(t), len(y)))
    W_edges = np.zeros((n_seg + 1, 6, 3))
    for j in range(n_seg):
        mask = seg == j
        t_eval = np.append(t[mask], t_edges[j + 1]) if not (mask.any() and t[mask][-1] == t_edges[j + 1]) else t[mask]
        sol = solve_ivp(
            _rate,
            (t_edges[j], t_edges[j + 1]),
            y,
            method="DOP853",
            t_eval=t_eval,
            rtol=rtol,
            atol=atol,
            args=(model, ballistic, e[j] if e[j].any() else None, with_partials),
        )
        if not sol.success:
            raise RuntimeError(f"orbit propagation failed: {sol.message}")
        out[mask] = sol.y[:, : mask.sum()].T
        y = sol.y[:, -1]
        if with_partials:
            W_edges[j + 1] = y[84:].reshape(6, 3)
    K = len(t)
    if not with_partials:
        return Trajectory(t, out, np.zeros((K, 6, 6)), np.zeros((K, 6)), np.zeros((K, 6, 3)), seg, W_edges)
    return Trajectory(
        t, out[:, :6], out[:, 6:42].reshape(K, 6, 6), out[:, 78:84], out[:, 84:].reshape(K, 6, 3), seg, W_edges
    )


@dataclass
class OrbitFit:
    """A converged fit: parameters p = [x0, (B), e], their covariance N^-1, the intervals' edges, the
    iterations it took and the fixes' RMS residual per axis [m]. ``e`` (J, 3) is zero without empirical
    accelerations."""

    model: ForceModel
    t0: float
    x0: np.ndarray
    ballistic: float
    e: np.ndarray
    covariance: np.ndarray
    t_edges: np.ndarray
    iterations: int
    residual_rms: float

    @property
    def n_params(self) -> int:
        return 6 + int(self.model.drag) + (self.e.size if self.model.empirical_interval_s else 0)

    def states(self, t: np.ndarray, with_covariance: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """Fitted states (K, 6) at the times t (within the fitted span) and their covariance (K, 6, 6):
        J C J' with J = dx(t)/dp."""
        traj = propagate(self.x0, self.ballistic, self.e, self.model, t, self.t_edges, with_partials=with_covariance)
        if not with_covariance:
            return traj.x, None
        return traj.x, state_covariance(traj, self.covariance, self.model.drag)


def state_covariance(traj: Trajectory, covariance: np.ndarray, drag: bool) -> np.ndarray:
    """F Cov(h) F' (K, 6, 6), the covariance of the states x(t) = F(t) h(t) (Trajectory): h = y_s + V(t) e_s
    with y_s = [x0 (, B)] + sum_{j<s} dW_j e_j, whose covariance and cross-covariance with e_s are carried from
    interval to interval."""
    F = traj.base(drag)
    nb = F.shape[2]
    if covariance.shape[0] == nb:
        return F @ covariance @ F.transpose(0, 2, 1)
    dW, V = traj.steps(nb)
    n_seg = len(dW)
    X = covariance[:nb].copy()  # Cov(y_s, p)
    Y = covariance[:nb, :nb].copy()  # Cov(y_s)
    Ys, Zs, Cee = np.empty((n_seg, nb, nb)), np.empty((n_seg, nb, 3)), np.empty((n_seg, 3, 3))
    for j in range(n_seg):
        e_rows = slice(nb + 3 * j, nb + 3 * j + 3)
        Z = X[:, e_rows]  # Cov(y_s, e_s)
        Ys[j], Zs[j], Cee[j] = Y, Z, covariance[e_rows, e_rows]
        step = dW[j] @ Z.T
        Y = Y + step + step.T + dW[j] @ Cee[j] @ dW[j].T
        X = X + dW[j] @ covariance[e_rows]
    seg = traj.segment
    cross = Zs[seg] @ V.transpose(0, 2, 1)
    Ch = Ys[seg] + cross + cross.transpose(0, 2, 1) + V @ Cee[seg] @ V.transpose(0, 2, 1)
    return F @ Ch @ F.transpose(0, 2, 1)


def normal_equations(
    traj: Trajectory, z: np.ndarray, sigma: float, n_params: int, drag: bool
) -> tuple[np.ndarray, np.ndarray]:
    """(N, b) = (sum H'H / sigma^2, sum H'(z - r) / sigma^2) over the fixes z (K, 3) at the trajectory's times,
    H = dr/dp = C G with C = F[:3] (Trajectory), summed interval by interval: with M = C'C / sigma^2, S_m the
    sum of M over the intervals from m on, T_j = sum M V and R_j = sum V'M V over interval j,

        N_bb = S_0,  N_b,e_j = Q_j = S_j+1 dW_j + T_j,  N_e_i,e_j = dW_i' Q_j (i < j),
        N_e_j,e_j = dW_j' S_j+1 dW_j + R_j

    (b likewise): O(K + J^2) instead of the O(K J^2) of forming H."""
    C = traj.base(drag)[:, :3]
    nb = C.shape[2]
    M = np.einsum("kai,kaj->kij", C, C) / sigma**2
    w = np.einsum("kai,ka->ki", C, z - traj.x[:, :3]) / sigma**2
    N, b = np.zeros((n_params, n_params)), np.zeros(n_params)
    N[:nb, :nb], b[:nb] = M.sum(axis=0), w.sum(axis=0)
    if n_params == nb:
        return N, b
    dW, V = traj.steps(nb)
    n_seg = len(dW)
    S = _sums_after(traj.per_interval(M))  # S_j+1, (J, nb, nb)
    Q = S @ dW + traj.per_interval(M @ V)
    N[:nb, nb:] = Q.transpose(1, 0, 2).reshape(nb, 3 * n_seg)
    N[nb:, :nb] = N[:nb, nb:].T
    Nee = N[nb:, nb:]
    np.matmul(dW.transpose(0, 2, 1).reshape(3 * n_seg, nb), N[:nb, nb:], out=Nee)  # block (i, j): dW_i' Q_j
    diagonal = dW.transpose(0, 2, 1) @ S @ dW + traj.per_interval(V.transpose(0, 2, 1) @ M @ V)
    for j in range(n_seg):  # the blocks i < j kept, i > j their mirror: filled in N, no n_params^2 temporaries
        rows = slice(3 * j, 3 * j + 3)
        Nee[rows, rows] = diagonal[j]
        Nee[rows, : 3 * j] = Nee[: 3 * j, rows].T
    ws = _sums_after(traj.per_interval(w))
    b[nb:] = (np.einsum("jab,ja->jb", dW, ws) + traj.per_interval(np.einsum("kab,ka->kb", V, w))).ravel()
    return N, b


def position_change(traj: Trajectory, dp: np.ndarray, drag: bool) -> np.ndarray:
    """dr(t) = C(t) G(t) dp (K, 3) at the trajectory's times, G's empirical part by prefix sums."""
    C = traj.base(drag)[:, :3]
    nb = C.shape[2]
    h = np.broadcast_to(dp[:nb], (len(C), nb)).copy()
    if len(dp) > nb:
        dW, V = traj.steps(nb)
        de = dp[nb:].reshape(-1, 3)
        before = np.zeros((len(dW) + 1, nb))
        before[1:] = np.cumsum(dW @ de[:, :, None], axis=0)[..., 0]  # sum_{j<s} dW_j de_j
        h += before[traj.segment] + (V @ de[traj.segment][:, :, None])[..., 0]
    return np.einsum("kai,ki->ka", C, h)


def information(
    model: ForceModel,
    x0: np.ndarray,
    ballistic: float,
    t: np.ndarray,
    sigma: float,
    empirical_sigma: float | None = None,
) -> OrbitFit:
    """The Fisher information of fixes at the times t (first = epoch) about p at the given true orbit, as an
    OrbitFit whose covariance is its inverse (the Cramer-Rao bound of any unbiased fit of p)."""
    t_edges = edges(t[0], t[-1], model.empirical_interval_s)
    n_e = 3 * (len(t_edges) - 1) if model.empirical_interval_s else 0
    e = np.zeros((len(t_edges) - 1, 3))
    traj = propagate(x0, ballistic, e, model, t, t_edges)
    n_params = 6 + int(model.drag) + n_e
    N, _ = normal_equations(traj, traj.x[:, :3], sigma, n_params, model.drag)
    covariance = _inverse(_factored(N, _prior(n_params, n_e, empirical_sigma)))
    return OrbitFit(model, float(t[0]), np.asarray(x0, float), ballistic, e, covariance, t_edges, 0, 0.0)


def _prior(n_params: int, n_e: int, empirical_sigma: float | None) -> np.ndarray:
    """The a-priori weights (n_params,), the diagonal of Lambda_prior: 1 / sigma_e^2 on the empirical
    accelerations, zero on the rest."""
    prior = np.zeros(n_params)
    if n_e:
        if not empirical_sigma or empirical_sigma <= 0:
            raise ValueError("empirical accelerations need a positive a-priori sigma [m/s^2]")
        prior[n_params - n_e :] = 1.0 / empirical_sigma**2
    return prior


def _factored(N: np.ndarray, prior: np.ndarray) -> tuple[np.ndarray, bool]:
    """The Cholesky factor of N + diag(prior), made in N's own memory (N is then the factor): N is symmetric
    positive definite (the fixes' information plus the a-priori weights), so Cholesky takes half the flops of an
    LU and no copy of the n_params^2 matrix (a day at 2 min: 2,346^2, 44 MB). Raises LinAlgError when it is not
    positive definite (too few fixes for the parameters and no prior on them)."""
    N[np.diag_indices_from(N)] += prior
    return cho_factor(N.T, overwrite_a=True, check_finite=False)  # N.T: N symmetric, its memory in LAPACK's order


def _inverse(factor: tuple[np.ndarray, bool]) -> np.ndarray:
    """The inverse of the matrix whose Cholesky factor is ``factor`` (LAPACK potri: a third of the flops of an LU
    inverse), both triangles filled."""
    c, lower = factor
    inverse, info = lapack.dpotri(c, lower=lower)
    if info != 0:
        raise np.linalg.LinAlgError(f"inverse from the Cholesky factor failed (LAPACK info={info})")
    triangle = np.tril(inverse) if lower else np.triu(inverse)
    return triangle + (np.tril(triangle, -1) if lower else np.triu(triangle, 1)).T


def initial_guess(t: np.ndarray, z: np.ndarray) -> np.ndarray:
    """State at t[0] from the first fixes: position of the first, velocity of a quadratic over the first five."""
    n = min(5, len(t))
    coef = np.polyfit(t[:n] - t[0], z[:n], 2)
    return np.concatenate([coef[2], coef[1]])


def fit_orbit(
    t: np.ndarray,
    z: np.ndarray,
    sigma: float,
    model: ForceModel,
    ballistic_guess: float = 0.0,
    empirical_sigma: float | None = None,
    max_iterations: int = 12,
    tol_m: float = 1.0e-5,
    warm_start_s: float = 5400.0,
) -> OrbitFit:
    """Batch least-squares orbit of one satellite from its position fixes z (K, 3) at times t (K,), noise
    sigma [m] per axis (module docstring). The state is first fitted over the first ``warm_start_s`` seconds
    (two-body start), then over the whole span; converged when the largest change of the fitted positions
    is below ``tol_m``."""
    t, z = np.asarray(t, float), np.asarray(z, float)
    x0, ballistic = initial_guess(t, z), float(ballistic_guess)
    if t[-1] - t[0] > 1.5 * warm_start_s:
        short = t <= t[0] + warm_start_s
        warm = fit_orbit(
            t[short],
            z[short],
            sigma,
            ForceModel(model.mu, model.re, model.zonals, False, model.rotation_rate),
            max_iterations=max_iterations,
            tol_m=tol_m,
            warm_start_s=warm_start_s,
        )
        x0 = warm.x0
    t_edges = edges(t[0], t[-1], model.empirical_interval_s)
    n_e = 3 * (len(t_edges) - 1) if model.empirical_interval_s else 0
    e = np.zeros((len(t_edges) - 1, 3))
    n_params = 6 + int(model.drag) + n_e
    prior = _prior(n_params, n_e, empirical_sigma)
    for iteration in range(1, max_iterations + 1):  # noqa: B007 - the count taken is returned
        traj = propagate(x0, ballistic, e, model, t, t_edges)
        N, b = normal_equations(traj, z, sigma, n_params, model.drag)
        p = np.concatenate([x0, [ballistic] if model.drag else [], e.ravel()[:n_e]])
        factor = _factored(N, prior)
        dp = cho_solve(factor, b - prior * p, check_finite=False)
        x0 = x0 + dp[:6]
        if model.drag:
            ballistic += dp[6]
        if n_e:
            e = e + dp[-n_e:].reshape(-1, 3)
        change = np.max(np.abs(position_change(traj, dp, model.drag)))
        if change < tol_m:
            break
    traj = propagate(x0, ballistic, e, model, t, t_edges, with_partials=False)
    rms = float(np.sqrt(np.mean((z - traj.x[:, :3]) ** 2)))
    return OrbitFit(model, float(t[0]), x0, ballistic, e, _inverse(factor), t_edges, iteration, rms)
