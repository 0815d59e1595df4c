"""An independent lost-in-space solver to cross-check the Pyramid identification: tetra3rs (PyPI; a Rust
implementation of the tetra3 pattern-hash plate solver), run on the same catalogue and the same centroids.

The solver database is generated from *this* package's catalogue (same stars, magnitudes, epoch, merged pairs)
written in tetra3rs' Gaia binary catalogue layout (header "GDR3", version 1 (u32), star count (u64); per star
source_id (i64), RA and Dec in degrees (f64), magnitude, pmRA, pmDec (f32), little-endian), with the HIP
number as source_id and zero proper motion (the positions are already at the catalogue's epoch). The database
is cached next to the catalogue, keyed by the catalogue's content and the field of view.

tetra3rs' centroid coordinates are pixels from the image centre (+x right, +y down) — camera.py's (u, v) minus
(W/2, H/2) — and its ``rotation_matrix_icrs_to_camera`` is the same camera-from-ICRS matrix as attitude.py's.
tetra3rs is imported only when a solver is built, so the package works without it.
"""

from __future__ import annotations

import hashlib
import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from star_tracker.camera import Camera
from star_tracker.catalogue import StarCatalogue, default_cache_dir, unit_to_radec

log = logging.getLogger(__name__)

GAIA_BINARY = np.dtype(
    [("source_id", "<i8"), ("ra", "<f8"), ("dec", "<f8"), ("mag", "<f4"), ("pmra", "<f4"), ("pmdec", "<f4")]
)


def write_tetra3_catalogue(catalogue: StarCatalogue, path: Path) -> None:
    """The catalogue in tetra3rs' Gaia binary layout (module docstring)."""
    ra, dec = unit_to_radec(catalogue.vectors)
    rec = np.zeros(len(catalogue), dtype=GAIA_BINARY)
    rec["source_id"], rec["ra"], rec["dec"] = catalogue.ids, np.degrees(ra), np.degrees(dec)
    rec["mag"] = catalogue.magnitudes
    with open(path, "wb") as f:
        f.write(b"GDR3" + np.uint32(1).astype("<u4").tobytes() + np.uint64(len(rec)).astype("<u8").tobytes())
        f.write(rec.tobytes())


@dataclass
class Tetra3Solution:
    ok: bool
    status: str
    index: np.ndarray
    """(N,) catalogue index of each centroid (−1 where not matched)."""
    attitude: np.ndarray | None
    """camera-from-ICRS matrix, None on failure."""
    solve_ms: float


class Tetra3Solver:
    """tetra3rs lost-in-space solves against the package's catalogue (module docstring)."""

    def __init__(
        self, catalogue: StarCatalogue, camera: Camera, cache_dir: Path | str | None = None, **solve_options
    ) -> None:
        import tetra3rs  # optional: a test_depend, only for the cross-check

        self.catalogue, self.camera = catalogue, camera
        directory = Path(cache_dir) if cache_dir is not None else default_cache_dir()
        digest = hashlib.sha256()
        for a in (catalogue.ids, catalogue.vectors, catalogue.magnitudes):
            digest.update(np.ascontiguousarray(a).tobytes())
        digest.update(f"{camera.fov_deg}|{tetra3rs.__version__}".encode())
        db_path = directory / f"tetra3_{digest.hexdigest()[:20]}.bin"
        self.db = None
        if db_path.exists():
            try:
                self.db = tetra3rs.SolverDatabase.load_from_file(str(db_path))
            except Exception as exc:
                log.warning("tetra3rs database %s is unreadable (%s): rebuilding it", db_path, exc)
        if self.db is None:
            directory.mkdir(parents=True, exist_ok=True)
            cat_path = db_path.with_suffix(f".{os.getpid()}.catalogue.bin")
            write_tetra3_catalogue(catalogue, cat_path)
            try:
                self.db = tetra3rs.SolverDatabase.generate_from_gaia(
                    str(cat_path),
                    max_fov_deg=camera.fov_deg,
                    star_max_magnitude=float(catalogue.magnitudes.max()),
                    epoch_proper_motion_year=None,
                )
            finally:
                cat_path.unlink(missing_ok=True)
            try:
                self.db.save_to_file(str(db_path))
            except OSError as exc:
                log.warning("cannot cache the tetra3rs database at %s (%s)", db_path, exc)
        self.model = tetra3rs.CameraModel.from_fov(camera.fov_deg, camera.width, camera.height)
        self.options = solve_options

    def solve(self, uv: np.ndarray, magnitudes: np.ndarray | None = None) -> Tetra3Solution:
        """Solve one frame's centroids uv (N, 2) (brightness from magnitudes when given)."""
        uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        xy = uv - self.camera.centre
        if magnitudes is not None:
            xy = np.column_stack([xy, 10.0 ** (-0.4 * np.asarray(magnitudes, dtype=float))])
        index = np.full(len(uv), -1, dtype=np.int64)
        result = self.db.solve_from_centroids(xy, camera_model=self.model, **self.options)
        if not result:
            return Tetra3Solution(False, str(result.status), index, None, float(result.solve_time_ms))
        rows = np.asarray(result.matched_centroids, dtype=np.int64)
        index[rows] = self.catalogue.index_of(np.asarray(result.matched_catalog_ids, dtype=np.int64))
        return Tetra3Solution(
            True,
            str(result.status),
            index,
            np.asarray(result.rotation_matrix_icrs_to_camera),
            float(result.solve_time_ms),
        )
