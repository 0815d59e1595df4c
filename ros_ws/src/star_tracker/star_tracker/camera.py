"""Pinhole star camera: projection of directions to pixel centroids and back, and the catalogue stars in view.

Frames and conventions.
- Camera frame: +z is the boresight, +x points along increasing pixel column u, +y along increasing pixel row
  v (right-handed: x right, y down, z out of the lens).
- Pixel coordinates (u, v): the image covers [0, W] × [0, H]; pixel (i, j) has its centre at (i + ½, j + ½);
  the optical axis pierces the image centre (W/2, H/2). (tetra3rs' centroid coordinates are u − W/2, v − H/2.)
- Projection (no distortion): u = W/2 + f x/z, v = H/2 + f y/z, with the focal length in pixels
  f = (W/2) / tan(FOV/2), FOV being the full field across the image width. Pixels are square.
- Attitude: A is the camera-from-ICRS rotation, b = A r (see attitude.py for the quaternion convention).

Default camera (:data:`DEFAULT_CAMERA`): 20° × 20°, 1024 × 1024 pixels (f = 2904 px: 71.0"/px at the centre,
70.3"/px on average), magnitude limit 6.0 (catalogue.load_catalogue). This is the class of the APS star
trackers flying on small and medium satellites: 1024 × 1024 CMOS detectors behind optics with fields of
roughly 15°–25° and on-board catalogues of a few thousand stars brighter than mag ~6 (e.g. the ASTRO APS and
HE-5AS families). With mag <= 6 the Hipparcos sky gives ~4 500 catalogue entries and ~40 stars per frame on
average (tests/test_star_camera.py checks the spread over random pointings), enough for lost-in-space
anywhere on the sky, while the paper's centroid noise σ = 0.005–0.03 px at 71"/px gives star-direction errors
of 0.35"–2", consistent with the arc-second attitude errors the paper reports.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from star_tracker.catalogue import StarCatalogue


@dataclass(frozen=True)
class Camera:
    """A distortion-free pinhole camera with square pixels."""

    fov_deg: float = 20.0
    """Full field of view across the image width (deg)."""
    width: int = 1024
    height: int = 1024

    def __post_init__(self) -> None:
        if not 0.0 < self.fov_deg < 179.0:
            raise ValueError(f"fov_deg must be in (0, 179), got {self.fov_deg}")
        if self.width < 1 or self.height < 1:
            raise ValueError(f"image size must be positive, got {self.width} x {self.height}")

    # The geometry is computed once per camera (the camera is frozen): the per-frame projections use it.
    @cached_property
    def focal_px(self) -> float:
        """Focal length in pixels, f = (W/2)/tan(FOV/2)."""
        return float(0.5 * self.width / np.tan(np.radians(self.fov_deg) / 2.0))

    @cached_property
    def ifov(self) -> float:
        """Angle subtended by one pixel at the image centre (rad/px), 1/f."""
        return 1.0 / self.focal_px

    @cached_property
    def centre(self) -> np.ndarray:
        """Principal point (u, v) in pixels (read-only)."""
        c = np.array([self.width / 2.0, self.height / 2.0])
        c.flags.writeable = False
        return c

    @property
    def half_diagonal(self) -> float:
        """Angle (rad) from the boresight to an image corner: the radius of the cone holding the image."""
        return float(np.arctan(0.5 * np.hypot(self.width, self.height) / self.focal_px))

    @property
    def max_separation(self) -> float:
        """Largest angle (rad) between two points of the image: corner to opposite corner."""
        return 2.0 * self.half_diagonal

    def project(self, v: np.ndarray) -> np.ndarray:
        """(N, 2) pixel coordinates (u, v) of camera-frame directions v (N, 3) (need not be unit vectors);
        NaN for directions at or behind the image plane's horizon (z <= 0)."""
        v = np.asarray(v, dtype=float)
        z = v[..., 2:]
        uv = np.full(v.shape[:-1] + (2,), np.nan)
        np.divide(self.focal_px * v[..., :2], z, out=uv, where=z > 0)
        uv += self.centre
        return uv

    def unproject(self, uv: np.ndarray) -> np.ndarray:
        """(N, 3) camera-frame unit vectors of pixel coordinates (N, 2); inverse of :meth:`project`."""
        xy = (np.asarray(uv, dtype=float) - self.centre) / self.focal_px
        x, y = xy[..., 0], xy[..., 1]
        norm = np.sqrt(x * x + y * y + 1.0)
        v = np.empty(xy.shape[:-1] + (3,))
        v[..., 0], v[..., 1], v[..., 2] = x, y, 1.0
        return v / norm[..., None]

    def to_tangent(self, uv: np.ndarray) -> np.ndarray:
        """Tangent-plane coordinates (x/z, y/z) of pixel coordinates (N, 2) (bench_msgs/StarCentroids'
        dimensionless positions): ((u, v) − centre) / f."""
        return (np.asarray(uv, dtype=float) - self.centre) / self.focal_px

    def from_tangent(self, xy: np.ndarray) -> np.ndarray:
        """Pixel coordinates of tangent-plane coordinates (N, 2); inverse of :meth:`to_tangent`."""
        return np.asarray(xy, dtype=float) * self.focal_px + self.centre

    def in_image(self, uv: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """True where a pixel coordinate lies in the image, at least ``margin`` pixels from its edges."""
        uv = np.asarray(uv, dtype=float)
        return (
            (uv[..., 0] >= margin)
            & (uv[..., 0] <= self.width - margin)
            & (uv[..., 1] >= margin)
            & (uv[..., 1] <= self.height - margin)
        )

    def stars_in_view(
        self, catalogue: StarCatalogue, attitude: np.ndarray, margin: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray]:
        """Catalogue indices (brightest first) and pixel coordinates (N, 2) of the stars imaged with the
        camera-from-ICRS attitude matrix ``attitude``: a k-d tree cone search around the boresight (the cone
        through the image corners), then the exact image rectangle."""
        A = np.asarray(attitude, dtype=float)
        idx = catalogue.cone(A[2], self.half_diagonal)  # boresight in ICRS = third row of A
        uv = self.project(catalogue.vectors[idx] @ A.T)
        inside = self.in_image(uv, margin)
        return idx[inside], uv[inside]

    def pixel_sigma_to_angle(self, sigma_px: float) -> float:
        """Angular standard deviation (rad) of a direction whose centroid has σ pixels per axis (at the image
        centre; the pinhole's scale shrinks by cos² of the off-axis angle towards the corners)."""
        return float(sigma_px) * self.ifov


DEFAULT_CAMERA = Camera()
"""20° × 20°, 1024 × 1024 (module docstring)."""
