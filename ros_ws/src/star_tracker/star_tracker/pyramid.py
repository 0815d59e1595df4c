"""Lost-in-space star identification with the Pyramid algorithm (Mortari, Samaan, Bruccoleri & Junkins 2004,
"The Pyramid star identification technique"), the identification the paper uses on its first frame.

1. Triangles. The observed stars (brightest first) are taken three at a time in Mortari's order (for
   dj = 1 …, dk = 1 …, i = 1 …: j = i + dj, k = j + dk), which changes all three stars between consecutive
   triangles so that one false star does not spoil a long run of them; first among the brightest
   ``max_stars``, then, if those are exhausted (false stars among the brightest), adding the next
   ``max_stars`` and so on, up to ``max_triangles`` triangles in all. For each side the k-vector (kvector.py)
   returns every catalogue pair whose angle is within ε of the observed one; the three candidate pair lists
   are joined on their shared stars into catalogue triangles (a, b, c) with angle(a, b) ≈ θ_ij,
   angle(a, c) ≈ θ_ik, angle(b, c) ≈ θ_jk, and a triangle must have the handedness of the observed one (sign
   of the triple product; a mirror image is not a rotation).
2. Pyramid. A candidate triangle is confirmed by a fourth star: the attitude of the triangle predicts the
   direction of every other observed star; the nearest catalogue star there must have all three angles to a,
   b, c within ε of the observed ones. False stars fail this; a wrong triangle almost always does too.
3. Attitude and the rest of the frame. The confirmed stars give a least-squares attitude (attitude.wahba);
   every observed star is then matched to the nearest catalogue star within the match radius (one catalogue
   star per centroid: the closest wins), the attitude is re-solved over all of them and the matching repeated.
4. Verification. The attitude is reported only if every identified star's residual is within the match radius
   and the number of identified stars m could not plausibly be a chance: with p the probability that a random
   direction has a catalogue star within the match radius (the local catalogue density times the radius'
   area), the probability of m − 3 or more chance matches among the n − 3 stars outside the triangle,
   P(X >= m − 3), X ~ Binomial(n − 3, p), must be at most ``max_false_alarm``. Otherwise the search goes on
   and, when the triangles run out, the result is a failure with its reason; it never guesses.

Tolerances (σ = centroid noise in pixels, ifov = rad per pixel): a star direction has σ_θ = σ·ifov per axis,
an inter-star angle ≈ √2 σ_θ, so ε = ``pair_sigmas``·√2·σ_θ + ``floor`` (the floor absorbs catalogue and
pinhole-scale errors), and the match radius is ``match_sigmas``·σ_θ + ``floor``.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
from scipy.special import bdtrc  # binomial survival function: binom.sf(k, n, p) = bdtrc(k, n, p)

from star_tracker.attitude import AttitudeSolution, wahba, wahba_matrix
from star_tracker.camera import Camera
from star_tracker.catalogue import ARCSEC, StarCatalogue, chord
from star_tracker.kvector import PairTable

UNIDENTIFIED = -1


@dataclass
class Identification:
    """The outcome of identifying one frame: identities and attitude, or a failure with its reason."""

    ok: bool
    reason: str
    """Why it failed ('' on success)."""
    index: np.ndarray
    """(N,) catalogue index of each centroid, UNIDENTIFIED (−1) for a centroid not identified."""
    attitude: AttitudeSolution | None = None
    triangles: int = 0
    """Triangles tried."""
    false_alarm: float = 1.0
    """Probability that the identified count is a chance (step 4); 1 on failure."""
    stats: dict = field(default_factory=dict)

    def hip(self, catalogue: StarCatalogue) -> np.ndarray:
        """(N,) HIP number of each centroid's star (−1 where not identified)."""
        return np.where(self.index >= 0, catalogue.ids[np.maximum(self.index, 0)], -1)


def triangle_order(n: int) -> Iterator[tuple[int, int, int]]:
    """Mortari's triangle sequence over n stars (module docstring, step 1)."""
    for dj in range(1, n - 1):
        for dk in range(1, n - dj):
            for i in range(0, n - dj - dk):
                yield i, i + dj, i + dj + dk


def triple_product(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """a · (b × c) along the last axis."""
    a, b, c = np.asarray(a), np.asarray(b), np.asarray(c)
    return (
        a[..., 0] * (b[..., 1] * c[..., 2] - b[..., 2] * c[..., 1])
        + a[..., 1] * (b[..., 2] * c[..., 0] - b[..., 0] * c[..., 2])
        + a[..., 2] * (b[..., 0] * c[..., 1] - b[..., 1] * c[..., 0])
    )


class _Angles:
    """The angles between a frame's observed directions b (N, 3), ``theta[i, j]``, computed a column at a time
    as the search needs them: a frame's search touches the columns of a few stars, and the whole N × N matrix
    was a sizeable share of a frame's identification."""

    def __init__(self, b: np.ndarray) -> None:
        self.b = b
        self._columns: dict[int, np.ndarray] = {}

    def column(self, j: int) -> np.ndarray:
        """(N,) the angles from every star to star j."""
        col = self._columns.get(j)
        if col is None:  # catalogue.angle_between's arithmetic, without np.linalg.norm's and np.clip's wrappers
            d = self.b - self.b[j]
            col = self._columns[j] = 2.0 * np.arcsin(np.minimum(np.sqrt((d * d).sum(axis=1)) / 2.0, 1.0))
        return col

    def __getitem__(self, ij: tuple[int, int]) -> float:
        return self.column(ij[1])[ij[0]]

    def block(self, rows: np.ndarray, cols: list[int]) -> np.ndarray:
        """(len(rows), len(cols)): theta[rows][:, cols]."""
        return np.stack([self.column(c)[rows] for c in cols], axis=1)


class _Near:
    """The nearest catalogue star to directions in the field of a candidate triangle: brute force over the
    catalogue stars within the identifier's reach of its first star a (StarCatalogue.neighbourhoods), a few
    hundred dot products instead of a k-d tree query. Exact: it answers only when every direction is close
    enough to a that each star within the bound of it lies in a's neighbourhood (chord triangle inequality),
    else the caller asks the k-d tree. Nearest by the largest dot product, the same order as the chord distance
    of unit vectors (ties aside)."""

    def __init__(self, identifier: PyramidIdentifier, a: int) -> None:
        self.stars = identifier._near[identifier._near_start[a] : identifier._near_start[a + 1]]
        self.vectors_t = identifier.catalogue.vectors.take(self.stars, axis=0).T  # a is the last column
        self.reach_chord = identifier._reach_chord

    def __call__(self, p: np.ndarray, bound: float) -> tuple[np.ndarray, np.ndarray] | None:
        """(rows of ``p`` (M, 3) with a catalogue star within chord ``bound``, that star), as
        ``tree.query(p, k=1, distance_upper_bound=bound)``'s finite rows; None when a row of ``p`` lies too far
        from a for the neighbourhood to hold every star within ``bound`` of it."""
        dots = p @ self.vectors_t
        if np.sqrt(max(2.0 - 2.0 * float(dots[:, -1].min()), 0.0)) + bound > self.reach_chord:
            return None
        best = dots.argmax(axis=1)
        top = dots.ravel().take(best + np.arange(0, dots.size, dots.shape[1]))
        rows = (top >= 1.0 - 0.5 * bound * bound).nonzero()[0]
        return rows, self.stars.take(best.take(rows))


class PyramidIdentifier:
    """Lost-in-space identification of a frame's centroids against a catalogue (module docstring)."""

    def __init__(
        self,
        catalogue: StarCatalogue,
        camera: Camera,
        sigma_px: float = 0.2,
        pair_sigmas: float = 4.0,
        match_sigmas: float = 6.0,
        floor_arcsec: float = 2.0,
        max_stars: int = 12,
        max_triangles: int = 1000,
        max_false_alarm: float = 1e-6,
        pair_table: PairTable | None = None,
    ) -> None:
        if sigma_px < 0:
            raise ValueError(f"sigma_px must be >= 0, got {sigma_px}")
        if max_stars < 4:
            raise ValueError(f"max_stars must be >= 4, got {max_stars}")
        self.catalogue = catalogue
        self.camera = camera
        sigma = camera.pixel_sigma_to_angle(sigma_px)
        self.sigma = sigma
        self.epsilon = pair_sigmas * np.sqrt(2.0) * sigma + floor_arcsec * ARCSEC
        self.match_radius = match_sigmas * sigma + floor_arcsec * ARCSEC
        self._match_chord = float(chord(self.match_radius))
        self._pyramid_chord = float(chord(50.0 * self.match_radius))
        """The pyramid test's search radius around each other star's predicted direction (step 2)."""
        self.max_stars = int(max_stars)
        self.max_triangles = int(max_triangles)
        self.max_false_alarm = float(max_false_alarm)
        self.pairs = pair_table if pair_table is not None else PairTable(catalogue, camera.max_separation)
        # _Near's neighbourhood radius: a frame spans camera.max_separation, the pyramid test searches 50 match
        # radii around a direction, and a candidate triangle's attitude puts a's centroid near a
        reach = camera.max_separation + 50.0 * self.match_radius + 4.0 * self.epsilon
        self._near_start, self._near = catalogue.neighbourhoods(reach)
        self._reach_chord = float(chord(reach)) * (1.0 - 1e-9)  # (the margin: rounding of the chord distances)
        cone = camera.half_diagonal
        self._cone_radius = cone
        self._cone_solid_angle = 2.0 * np.pi * (1.0 - np.cos(cone))

    # ------------------------------------------------------------------------------------------------ API
    def identify(self, uv: np.ndarray, magnitudes: np.ndarray | None = None) -> Identification:
        """Identify the centroids uv (N, 2) (pixels); ``magnitudes`` orders them brightest first for the
        triangles (the given order otherwise). Never raises on a frame's content."""
        uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        finite = np.all(np.isfinite(uv), axis=1)
        index = np.full(len(uv), UNIDENTIFIED, dtype=np.int64)
        b = self.camera.unproject(np.where(finite[:, None], uv, 0.0))
        mags = None if magnitudes is None else np.asarray(magnitudes, dtype=float).ravel()
        if mags is not None and len(mags) != len(uv):  # not one magnitude per centroid: ignore them
            mags = None
        order = np.arange(len(uv)) if mags is None else np.argsort(mags, kind="stable")
        order = order[finite[order]]
        result = self.identify_vectors(b[order])
        index[order] = result.index
        result.index = index
        return result

    def identify_vectors(self, b: np.ndarray) -> Identification:
        """Identify camera-frame unit vectors b (N, 3), brightest first."""
        b = np.asarray(b, dtype=float).reshape(-1, 3)
        n = len(b)
        none = np.full(n, UNIDENTIFIED, dtype=np.int64)
        if n < 4:
            return Identification(False, f"too few stars: {n} centroids, the Pyramid needs 4", none)
        theta = _Angles(b)
        cache: dict[tuple[int, int], list[np.ndarray]] = {}
        tried, candidates = 0, 0
        for i, j, k in self._triangles(n):
            if tried >= self.max_triangles:
                return Identification(
                    False,
                    f"no confirmed triangle within the limit of {self.max_triangles} "
                    f"triangles ({candidates} catalogue candidates tested)",
                    none,
                    triangles=tried,
                )
            tried += 1
            for a, bb, c in self._triangle_candidates(b, theta, i, j, k, cache):
                candidates += 1
                result = self._confirm(b, theta, (i, j, k), (a, bb, c))
                if result is not None:
                    result.triangles = tried
                    result.stats["candidates"] = candidates
                    return result
        return Identification(
            False,
            f"no confirmed triangle among the {tried} triangles of the {n} centroids "
            f"({candidates} catalogue candidates tested)",
            none,
            triangles=tried,
        )

    def _triangles(self, n: int) -> Iterator[tuple[int, int, int]]:
        """Triangles of the brightest ``max_stars`` in Mortari's order, then, if none was confirmed (false
        stars among the brightest), those of the next ``max_stars`` stars that were not tried yet, and so on."""
        done = 0
        size = min(n, self.max_stars)
        while True:
            for tri in triangle_order(size):
                if tri[2] >= done:
                    yield tri
            if size == n:
                return
            done, size = size, min(n, size + self.max_stars)

    def match(self, b: np.ndarray, attitude: np.ndarray, radius: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Catalogue index of the nearest catalogue star within ``radius`` (default: the match radius) of each
        observed direction b (N, 3) mapped to ICRS by the camera-from-ICRS ``attitude`` (−1 where none), each
        catalogue star going to its closest centroid only; and the angular distances (inf where none). This
        identifies the stars of a frame once the attitude is known (new stars entering the field too)."""
        b = np.asarray(b, dtype=float).reshape(-1, 3)
        index, rows, d = self._nearest(
            b, np.asarray(attitude, dtype=float), self._match_chord if radius is None else chord(radius)
        )
        dist = np.full(len(b), np.inf)
        dist[rows] = 2.0 * np.arcsin(np.minimum(d[rows] / 2.0, 1.0))
        return index, dist

    def _nearest(
        self, b: np.ndarray, attitude: np.ndarray, bound: float, near: _Near | None = None
    ) -> tuple[np.ndarray, ...]:
        """:meth:`match`'s catalogue indices (N,), with the rows that have one and every row's chord distance
        (None when ``near`` answered)."""
        index = np.full(len(b), UNIDENTIFIED, dtype=np.int64)
        if len(b) == 0:
            return index, np.zeros(0, dtype=np.intp), np.zeros(0)
        p = b @ attitude  # rows: Aᵀ b
        rows, found, d = self._query(p, bound, near)
        if len(rows):
            stars = np.sort(found)
            if (stars[1:] == stars[:-1]).any():  # a catalogue star near two centroids: the closest one keeps it
                closeness = (
                    d[rows]
                    if d is not None
                    else -np.einsum("ij,ij->i", p[rows], self.catalogue.vectors.take(found, axis=0))
                )
                order = closeness.argsort(kind="stable")
                rows, found = rows[order], found[order]
                _, first = np.unique(found, return_index=True)
                rows, found = rows[first], found[first]
            index[rows] = found
        return index, rows, d

    def _query(
        self, p: np.ndarray, bound: float, near: _Near | None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """(rows of ``p`` (M, 3) with a catalogue star within chord ``bound``, that nearest star, every row's
        chord distance): by ``near`` when it answers (then no distances), else by the catalogue's k-d tree."""
        if near is not None:
            found = near(p, bound)
            if found is not None:
                return found[0], found[1], None
        d, idx = self.catalogue.tree.query(p, k=1, distance_upper_bound=bound)
        rows = np.isfinite(d).nonzero()[0]
        return rows, idx[rows], d

    # --------------------------------------------------------------------------------------------- steps
    def _side(self, theta: _Angles, i: int, j: int, cache: dict, indexed: bool = False) -> list[np.ndarray]:
        """Directed candidate pairs (x, y) of observed side (i, j) — every catalogue pair {x, y} whose angle is
        within ε of θ_ij, both ways round — sorted by x; ``indexed``: also the start and count of each catalogue
        star's run in x (a CSR index, so that joins need no search; built only for a side joined as the second)."""
        key = (i, j)
        side = cache.get(key)
        if side is None:
            f, s = self.pairs.lookup(theta[i, j], self.epsilon)
            x, y = np.concatenate([f, s]), np.concatenate([s, f])
            order = x.argsort(kind="stable")
            side = cache[key] = [x[order], y[order]]
        if indexed and len(side) == 2:
            count = np.bincount(side[0], minlength=self.pairs.n_stars)
            side += [count.cumsum() - count, count]
        return side

    def _triangle_candidates(self, b: np.ndarray, theta: _Angles, i: int, j: int, k: int, cache: dict) -> np.ndarray:
        """(M, 3) catalogue triangles (a, b, c) matching observed (i, j, k) (module docstring, step 1): the
        candidate pairs of sides (i, j) and (i, k) joined on their common star a, then the third side's angle
        θ_jk checked directly on the catalogue vectors."""
        x1, y1 = self._side(theta, i, j, cache)[:2]
        _, y2, start2, count2 = self._side(theta, i, k, cache, indexed=True)
        cnt = count2.take(x1)
        total = int(cnt.sum())
        if total == 0:
            return np.empty((0, 3), dtype=np.int64)
        first = cnt.cumsum() - cnt  # each (i, j) pair's first joined row
        tc = y2.take(np.arange(total) + (start2.take(x1) - first).repeat(cnt))
        tb = y1.repeat(cnt)
        v = self.catalogue.vectors
        cos_bc = np.einsum("ij,ij->i", v.take(tb, axis=0), v.take(tc, axis=0))  # (take: a fraction of v[tb]'s cost)
        t = theta[j, k]
        ok = (
            (tb != tc)
            & (cos_bc >= np.cos(min(t + self.epsilon, np.pi)))
            & (cos_bc <= np.cos(max(t - self.epsilon, 0.0)))
        )
        ok = ok.nonzero()[0]
        if len(ok) == 0:
            return np.empty((0, 3), dtype=np.int64)
        tri = np.stack([x1.repeat(cnt)[ok], tb[ok], tc[ok]], axis=1).astype(np.int64)
        # handedness: a rotation keeps the sign of the triple product (skip the test for a flat triangle)
        (a0, a1, a2), (b0, b1, b2), (c0, c1, c2) = b[[i, j, k]].tolist()
        s_obs = a0 * (b1 * c2 - b2 * c1) + a1 * (b2 * c0 - b0 * c2) + a2 * (b0 * c1 - b1 * c0)  # triple_product
        if abs(s_obs) > 4.0 * self.epsilon * max(theta[i, j], theta[i, k]):
            corners = v.take(tri, axis=0)
            s_cat = triple_product(corners[:, 0], corners[:, 1], corners[:, 2])
            tri = tri[np.sign(s_cat) == np.sign(s_obs)]
        return tri

    def _confirm(
        self, b: np.ndarray, theta: _Angles, obs: tuple[int, int, int], cat: tuple[int, int, int]
    ) -> Identification | None:
        """Steps 2–4 for one catalogue triangle; None when it is not confirmed."""
        v = self.catalogue.vectors
        obs_i, cat_i = list(obs), list(cat)
        A = wahba_matrix(b.take(obs_i, axis=0), v.take(cat_i, axis=0))
        others = np.array([r for r in range(len(b)) if r not in obs], dtype=np.intp)
        if len(others) == 0:
            return None
        # step 2: nearest catalogue star to each other star's predicted direction, then the pyramid test
        near = _Near(self, cat_i[0])
        hit, cands, _ = self._query(b.take(others, axis=0) @ A, self._pyramid_chord, near)
        if len(hit) == 0:
            return None
        rows = others[hit]
        cat_ang = np.arccos(np.clip(v.take(cands, axis=0) @ v.take(cat_i, axis=0).T, -1.0, 1.0))  # (M, 3)
        confirmed = (np.abs(theta.block(rows, obs_i) - cat_ang) <= self.epsilon).all(axis=1)
        confirmed &= (cands != cat_i[0]) & (cands != cat_i[1]) & (cands != cat_i[2])
        if not confirmed.any():
            return None
        # step 3: attitude from the pyramid, then every star matched, twice
        rows_c, cands_c = rows[confirmed], cands[confirmed]
        A = wahba_matrix(np.vstack([b[obs_i], b[rows_c]]), np.vstack([v[cat_i], v[cands_c]]))
        index = self._nearest(b, A, self._match_chord, near)[0]
        for _ in range(2):
            ident = index >= 0
            if int(ident.sum()) < 4:
                return None
            A = wahba_matrix(b[ident], v[index[ident]])
            index, previous = self._nearest(b, A, self._match_chord, near)[0], index
            if np.array_equal(index, previous):  # the same stars give the same attitude: matching again
                break  # would repeat this match exactly
        ident = index >= 0
        m = int(ident.sum())
        if m < 4:
            return None
        solution = wahba(b[ident], v[index[ident]], self.sigma if self.sigma > 0 else ARCSEC)
        if (solution.residuals > self.match_radius).any():
            return None
        # step 4: could this many matches be chance?
        n = len(b)
        density = self.catalogue.cone_count(solution.matrix[2], self._cone_radius) / self._cone_solid_angle
        p = min(1.0, density * np.pi * self.match_radius**2)
        false_alarm = float(bdtrc(m - 3 - 1, n - 3, p))
        if false_alarm > self.max_false_alarm:
            return None
        full = np.full(n, UNIDENTIFIED, dtype=np.int64)
        full[ident] = index[ident]
        return Identification(
            True, "", full, solution, false_alarm=false_alarm, stats={"pyramid_confirmations": int(confirmed.sum())}
        )
