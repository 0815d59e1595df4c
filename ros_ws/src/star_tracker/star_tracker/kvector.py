"""The k-vector range search (Mortari 1997, "Search-less algorithm for star pattern recognition"; Mortari &
Neta 2000) and the catalogue's star-pair table it indexes.

Given n sorted values y_0 <= ... <= y_{n-1}, the straight line z(i) = q + m i through (0, y_0 − ξ) and
(n − 1, y_{n-1} + ξ) (ξ a relative margin so that both ends are strictly inside) defines the k-vector

    k[i] = #{ j : y_j < z(i) },   i = 0 … n − 1.

For a query [ya, yb] the bins are found by arithmetic, without a search:

    lb = floor((ya − q)/m),   ub = floor((yb − q)/m)   so that   z(lb) <= ya < z(lb + 1),  z(ub) <= yb < z(ub + 1).

Every value below k[lb] is < z(lb) <= ya (out), every value from k[lb + 1] on is >= z(lb + 1) > ya; so the
first value >= ya lies in the single bin [k[lb], k[lb + 1]), which holds about one value on average (the line
follows the sorted data), and likewise the last value <= yb lies in [k[ub], k[ub + 1]). Trimming those two bins
(a search over ~1 element each) makes the answer exact: every j with ya <= y_j <= yb, nothing else. The cost
is O(1) plus the size of the answer.

Pair table (:class:`PairTable`): every pair of catalogue stars closer than the largest angle two points of the
image can subtend (camera.max_separation), sorted by their angular distance, with the k-vector over those
angles. The Pyramid identification (pyramid.py) asks it for every catalogue pair whose angle lies in
[θ − ε, θ + ε].
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from star_tracker.catalogue import StarCatalogue, angle_between, chord


class KVector:
    """Exact range queries over a fixed set of values by the k-vector (module docstring)."""

    def __init__(self, values: np.ndarray, margin: float = 1e-9) -> None:
        y = np.asarray(values, dtype=float).ravel()
        if y.size < 2:
            raise ValueError("the k-vector needs at least two values")
        if not np.all(np.isfinite(y)):
            raise ValueError("the k-vector's values must be finite")
        self.order = np.argsort(y, kind="stable")
        """Index into the given values of each sorted value."""
        self.sorted = y[self.order]
        n = len(y)
        xi = margin * max(abs(self.sorted[0]), abs(self.sorted[-1]), 1.0)
        lo, hi = self.sorted[0] - xi, self.sorted[-1] + xi
        self.m = (hi - lo) / (n - 1)
        self.q = lo
        self.k = np.searchsorted(self.sorted, self.q + self.m * np.arange(n), side="left")
        """k[i] = number of values strictly below z(i)."""

    def __len__(self) -> int:
        return len(self.sorted)

    def span(self, ya: float, yb: float) -> tuple[int, int]:
        """(start, stop): the sorted positions start … stop − 1 hold exactly the values in [ya, yb]."""
        n = len(self.sorted)
        if not yb >= ya:  # also false for NaN
            return 0, 0
        return self._first_at_least(ya, n), self._first_above(yb, n)

    def _first_at_least(self, y: float, n: int) -> int:
        t = (y - self.q) / self.m
        if t < 0:
            return 0
        if t >= n - 1:
            return n
        lb = int(t)
        a, b = self.k[lb], self.k[lb + 1]
        i = int(a + self.sorted[a:b].searchsorted(y, side="left"))
        # guard against t rounding across a bin edge: the answer must separate < y from >= y
        if (i > 0 and self.sorted[i - 1] >= y) or (i < n and self.sorted[i] < y):
            i = int(np.searchsorted(self.sorted, y, side="left"))
        return i

    def _first_above(self, y: float, n: int) -> int:
        t = (y - self.q) / self.m
        if t < 0:
            return 0
        if t >= n - 1:
            return n
        ub = int(t)
        a, b = self.k[ub], self.k[ub + 1]
        i = int(a + self.sorted[a:b].searchsorted(y, side="right"))
        if (i > 0 and self.sorted[i - 1] > y) or (i < n and self.sorted[i] <= y):
            i = int(np.searchsorted(self.sorted, y, side="right"))
        return i

    def query(self, ya: float, yb: float) -> np.ndarray:
        """Indices (into the values given to the constructor) of every value in [ya, yb], in value order."""
        start, stop = self.span(ya, yb)
        return self.order[start:stop]


class PairTable:
    """Catalogue star pairs within ``max_angle`` of each other, sorted by angle, k-vector indexed."""

    def __init__(self, catalogue: StarCatalogue, max_angle: float) -> None:
        pairs = cKDTree(catalogue.vectors).query_pairs(chord(max_angle), output_type="ndarray")
        if len(pairs) < 2:
            raise ValueError(f"fewer than two catalogue pairs within {np.degrees(max_angle):.2f} deg")
        angles = angle_between(catalogue.vectors[pairs[:, 0]], catalogue.vectors[pairs[:, 1]])
        self.max_angle = float(max_angle)
        self.kvector = KVector(angles)
        order = self.kvector.order
        index_type = np.int16 if len(catalogue) <= np.iinfo(np.int16).max else np.int32
        self.first = pairs[order, 0].astype(index_type)
        """(P,) catalogue index of one star of each pair, pairs sorted by angle: int16 when the catalogue
        allows (a Hipparcos catalogue to magnitude 6-7 does), so that sorting a lookup's stars is numpy's radix
        sort, much faster than an int32 sort (pyramid.py sorts every side it looks up)."""
        self.second = pairs[order, 1].astype(index_type)
        self.angles = angles[order]
        self.n_stars = len(catalogue)

    def __len__(self) -> int:
        return len(self.angles)

    def lookup(self, angle: float, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
        """The two catalogue indices (unordered) of every pair whose angle is within ``tolerance`` of
        ``angle`` (rad)."""
        start, stop = self.kvector.span(angle - tolerance, angle + tolerance)
        return self.first[start:stop], self.second[start:stop]
