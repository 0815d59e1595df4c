"""Joint probabilistic data association (JPDA; Fortmann, Bar-Shalom & Scheffe 1983; the paper's eqs. 4–12 and
Table 2) as a data associator over tracker_filters.association's hypotheses.

Gating (eq. 5): detection j is valid for target r when d²_rj = ν_rjᵀ S_r⁻¹ ν_rj <= δ (the hypothesiser's gate;
P_G = chi2.cdf(δ, n_z) is the probability that the gate holds the target's own measurement).

Clusters. Targets are linked when their gates share a detection; each connected group of targets with the
detections in their gates is a cluster, and the joint events of different clusters are independent, so the
events are enumerated per cluster: the cost stays bounded by the largest cluster, not the frame. A target
alone in its cluster (the common case for stars) has the single-target PDA weights, computed for all such
targets at once without enumeration (``_singletons``; the tests check both paths give the same weights). A cluster
whose event count Π_r (1 + n_r) (n_r: detections in target r's gate) exceeds ``max_events`` is not enumerated:
each of its targets gets its single-target PDA weights instead (the mutual exclusion is dropped), and the
count of such clusters is kept in ``approximated``.

Feasible joint events θ (eqs. 8–9): each target takes at most one detection of its gate, each detection goes
to at most one target; the detections of the cluster left over (φ of them) are clutter. Event probability
(eq. 10), with δ_r = 1 when target r is detected in θ and N_rj = N(ν_rj; 0, S_r):

    parametric (clutter density λ given, per unit area of the image):
        P(θ) ∝ λ^φ · Π_{r detected} P_D N_rj · Π_{r missed} (1 − P_D P_G)
    non-parametric (λ = None, the paper's form):
        P(θ) ∝ φ!/V^φ · Π_{r detected} P_D N_rj · Π_{r missed} (1 − P_D P_G),
        V = Σ_{r in cluster} V_r,  V_r = c_nz δ^{n_z/2} |S_r|^{1/2}   (eq. 11)

with c_nz = 2, π, 4π/3 for n_z = 1, 2, 3 (the volume of the unit ball; the paper prints 3π/4 for n_z = 3, a
slip). (The paper writes the miss factor as 1 − P_D, i.e. P_G = 1; with the gate probability the factor is
the exact one for a gated target, and the two agree when δ is large.) The paper sums V over all targets; here
the sum runs over the cluster's targets, where its clutter lies. λ = 0 is taken as the limit λ → 0: among the
feasible events only those leaving the fewest detections to clutter keep weight.

Marginals (eq. 12): β_rj = Σ_θ P(θ) [θ assigns j to r], β_r0 = Σ_θ P(θ) [r missed in θ]. Each target's
result is an association.Association with weights [β_r0, β_r1, …, β_rN].
"""

from __future__ import annotations

from math import lgamma, log, pi

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from tracker_filters.association import Association, Hypotheses

UNIT_BALL = {1: 2.0, 2: pi, 3: 4.0 * pi / 3.0}
"""c_nz of eq. 11: the volume of the unit ball in n_z dimensions."""
TINY_DENSITY = 1e-300
"""λ = 0 is evaluated as this density (module docstring: the limit λ → 0)."""


def gate_volume(S: np.ndarray, gate: float) -> float:
    """V_r = c_nz δ^{n_z/2} |S|^{1/2} (eq. 11)."""
    n = S.shape[-1]
    c = UNIT_BALL.get(n, pi ** (n / 2) / np.exp(lgamma(n / 2 + 1)))
    return float(c * gate ** (n / 2) * np.sqrt(np.linalg.det(S)))


def clusters(gated: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """(targets, detections) of every connected group of targets sharing gated detections; a target with
    nothing in its gate is a cluster of its own with no detections."""
    T, N = gated.shape
    r, j = np.nonzero(gated)
    graph = coo_matrix((np.ones(len(r)), (r, T + j)), shape=(T + N, T + N))
    n, label = connected_components(graph, directed=False)
    out = []
    for c in np.unique(label[:T]):
        members = np.flatnonzero(label == c)
        out.append((members[members < T], members[members >= T] - T))
    return out


class JointProbabilisticAssociator:
    """JPDA weights per target (module docstring); the ``associate`` of tracker_filters' DataAssociator."""

    def __init__(self, p_detect: float, clutter_density: float | None = None, max_events: int = 20000) -> None:
        if not 0.0 < p_detect <= 1.0:
            raise ValueError(f"p_detect must be in (0, 1], got {p_detect}")
        if clutter_density is not None and clutter_density < 0:
            raise ValueError(f"clutter_density must be >= 0 or None, got {clutter_density}")
        if max_events < 1:
            raise ValueError(f"max_events must be >= 1, got {max_events}")
        self.p_detect = float(p_detect)
        self.clutter_density = None if clutter_density is None else float(clutter_density)
        self.max_events = int(max_events)
        self.approximated = 0
        """Clusters too large to enumerate, resolved by single-target PDA (module docstring)."""
        self.largest_cluster = 0

    def associate(self, hypotheses: Hypotheses) -> list[Association]:
        weights = self.weights(hypotheses)
        detection = np.argmax(weights, axis=1) - 1  # the most probable hypothesis; column 0, the miss, gives -1
        return [Association(int(j), w) for j, w in zip(detection, weights)]

    def weights(self, hypotheses: Hypotheses) -> np.ndarray:
        """(T, N + 1) β of every target: [β_r0, β_r1, …, β_rN] (eq. 12), the rows of :meth:`associate`."""
        T, N = hypotheses.n_tracks, hypotheses.n_detections
        weights = np.zeros((T, N + 1))
        weights[:, 0] = 1.0
        if N == 0 or T == 0:
            return weights
        gated = hypotheses.gated & np.isfinite(hypotheses.log_likelihood)
        # a target whose gated detections are in no other target's gate is a cluster of its own: its weights
        # are the single-target PDA's, computed for all such targets at once over their gated pairs only
        pair_r, pair_j = np.divmod(np.flatnonzero(gated), N)  # the gated pairs, by target
        shared = (np.bincount(pair_j, minlength=N) > 1)[pair_j]
        alone = np.ones(T, dtype=bool)
        alone[pair_r[shared]] = False
        single = alone[pair_r]
        self._singletons(hypotheses, pair_r[single], pair_j[single], weights)
        rest = ~alone
        if rest.any():
            rows = np.flatnonzero(rest)
            for targets, detections in clusters(gated[rows]):
                targets = rows[targets]
                if len(detections) == 0:
                    continue
                self.largest_cluster = max(self.largest_cluster, len(targets))
                n_events = float(np.prod(1.0 + gated[np.ix_(targets, detections)].sum(axis=1)))
                if n_events > self.max_events:
                    self.approximated += 1
                    for r in targets:
                        own = np.flatnonzero(gated[r])
                        weights[r] = 0.0
                        weights[r, np.r_[0, own + 1]] = self._cluster(hypotheses, np.array([r]), own)[0]
                    continue
                beta = self._cluster(hypotheses, targets, detections)
                cols = np.r_[0, detections + 1]
                for row, r in enumerate(targets):
                    weights[r] = 0.0
                    weights[r, cols] = beta[row]
        return weights

    def _singletons(self, hyp: Hypotheses, r: np.ndarray, j: np.ndarray, weights: np.ndarray) -> None:
        """The weights of every single-target cluster at once, from their gated pairs (target r, detection j;
        by target) (the events: missed, or one of its m gated detections, the others clutter), the same
        numbers :meth:`_cluster` gives for one target:

            β_j ∝ P_D N_j · c(m − 1),   β_0 ∝ (1 − P_D P_G) · c(m),
            c(φ) = λ^φ (parametric) or φ!/V^φ (non-parametric, V the target's gate volume)."""
        if len(r) == 0:
            return
        self.largest_cluster = max(self.largest_cluster, 1)
        P_D, P_G = self.p_detect, hyp.gate_probability
        counts = np.bincount(r)
        targets = np.flatnonzero(counts)
        m = counts[targets]  # gated detections per target
        first = np.cumsum(m) - m  # each target's first pair
        own = np.repeat(np.arange(len(targets)), m)  # pair -> its target's row
        log_det = np.log(P_D) + hyp.log_likelihood[r, j]
        log_miss = np.log(1.0 - P_D * P_G) if P_D * P_G < 1.0 else -np.inf
        if self.clutter_density is None:
            S = hyp.S[targets, j[first]]  # (K, d, d)
            n = S.shape[-1]
            c = UNIT_BALL.get(n, pi ** (n / 2) / np.exp(lgamma(n / 2 + 1)))
            log_v = np.log(c * hyp.gate ** (n / 2) * np.sqrt(np.linalg.det(S)))
            # c(m − 1)/c(m) = V/m: relative to the miss, a detection is weighed by V/m
            log_pair = log_det + (log_v - np.log(m))[own]
        else:
            log_pair = log_det - np.log(max(self.clutter_density, TINY_DENSITY))  # c(m − 1)/c(m) = 1/λ
        top = np.maximum(np.maximum.reduceat(log_pair, first), log_miss)
        p_pair, p_miss = np.exp(log_pair - top[own]), np.exp(log_miss - top)
        total = p_miss + np.add.reduceat(p_pair, first)
        weights[targets, 0] = p_miss / total
        weights[r, j + 1] = p_pair / total[own]

    def _cluster(self, hyp: Hypotheses, targets: np.ndarray, detections: np.ndarray) -> np.ndarray:
        """(len(targets), 1 + len(detections)) weights [β_r0, β_r(detections)…] of one cluster."""
        m = len(detections)
        P_D, P_G = self.p_detect, hyp.gate_probability
        log_miss = log(1.0 - P_D * P_G) if P_D * P_G < 1.0 else -np.inf
        # log of the detected factor P_D N_rj for each (target, detection of the cluster); -inf outside gates
        ll = hyp.log_likelihood[np.ix_(targets, detections)]
        log_det = np.where(hyp.gated[np.ix_(targets, detections)] & np.isfinite(ll), log(P_D) + ll, -np.inf)
        if self.clutter_density is None:
            volume = sum(gate_volume(hyp.S[r, detections[0]], hyp.gate) for r in targets)
            log_clutter = [lgamma(phi + 1) - phi * log(volume) for phi in range(m + 1)]
        else:
            lam = max(self.clutter_density, TINY_DENSITY)
            log_clutter = [phi * log(lam) for phi in range(m + 1)]
        options = [np.flatnonzero(np.isfinite(row)) for row in log_det]
        events: list[tuple[tuple[int, ...], float]] = []
        assign = [-1] * len(targets)
        used = np.zeros(m, dtype=bool)

        def visit(r: int, logw: float, n_assigned: int) -> None:
            if r == len(targets):
                events.append((tuple(assign), logw + log_clutter[m - n_assigned]))
                return
            assign[r] = -1
            visit(r + 1, logw + log_miss, n_assigned)
            for j in options[r]:
                if not used[j]:
                    used[j] = True
                    assign[r] = int(j)
                    visit(r + 1, logw + log_det[r, j], n_assigned + 1)
                    used[j] = False
            assign[r] = -1

        visit(0, 0.0, 0)
        logs = np.array([lw for _, lw in events])
        beta = np.zeros((len(targets), m + 1))
        if not np.isfinite(logs).any():  # no event possible (e.g. P_D = 1 and a detection no target may take)
            beta[:, 0] = 1.0
            return beta
        p = np.exp(logs - logs.max())
        p /= p.sum()
        for (a, _), pe in zip(events, p):
            for row, j in enumerate(a):
                beta[row, j + 1] += pe  # j = -1 adds to column 0, the miss
        return beta
