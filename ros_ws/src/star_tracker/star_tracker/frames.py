"""Star-camera frames: the centroids a camera reports for an attitude, with the truth of where each came from.

A frame holds the centroid of every catalogue star in the image that is detected (probability P_D each), with
Gaussian centroid noise of σ pixels per axis, plus false stars (hot pixels, debris, glints) at uniform random
positions: a fixed number per frame and/or a Poisson number with a given mean. Each centroid carries an
instrument magnitude (the catalogue's plus Gaussian noise; false stars uniform over a magnitude range) and the
list is sorted brightest first, as a centroiding stage reports it. The catalogue index behind each centroid
(−1 for a false star) is truth, for scoring only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from star_tracker.camera import Camera
from star_tracker.catalogue import StarCatalogue

FALSE_STAR = -1


@dataclass
class Frame:
    """One frame's centroids (brightest first) and their truth."""

    uv: np.ndarray
    """(N, 2) pixel coordinates (camera.py conventions)."""
    magnitudes: np.ndarray
    """(N,) measured magnitudes."""
    truth: np.ndarray
    """(N,) catalogue index of the star behind each centroid, FALSE_STAR (−1) for a false star."""
    attitude: np.ndarray
    """(3, 3) true camera-from-ICRS attitude."""

    def __len__(self) -> int:
        return len(self.uv)

    @property
    def n_false(self) -> int:
        return int(np.sum(self.truth == FALSE_STAR))


def random_attitude(rng: np.random.Generator) -> np.ndarray:
    """A camera-from-ICRS attitude uniformly distributed over rotations."""
    return Rotation.random(random_state=rng).as_matrix()


def simulate_frame(
    catalogue: StarCatalogue,
    camera: Camera,
    attitude: np.ndarray,
    rng: np.random.Generator,
    sigma_px: float = 0.2,
    p_detect: float = 1.0,
    n_false: int = 0,
    false_rate: float = 0.0,
    false_magnitudes: tuple[float, float] = (2.0, 6.0),
    mag_sigma: float = 0.1,
    margin_px: float = 0.0,
) -> Frame:
    """The centroids of one frame (module docstring). A star whose noisy centroid leaves the image is lost."""
    if not 0.0 <= p_detect <= 1.0:
        raise ValueError(f"p_detect must be in [0, 1], got {p_detect}")
    idx, uv = camera.stars_in_view(catalogue, attitude, margin_px)
    keep = rng.random(len(idx)) < p_detect
    idx, uv = idx[keep], uv[keep] + rng.normal(0.0, sigma_px, (int(keep.sum()), 2))
    inside = camera.in_image(uv)
    idx, uv = idx[inside], uv[inside]
    mags = catalogue.magnitudes[idx] + rng.normal(0.0, mag_sigma, len(idx))
    n_f = int(n_false) + (int(rng.poisson(false_rate)) if false_rate > 0 else 0)
    f_uv = rng.uniform([0.0, 0.0], [camera.width, camera.height], (n_f, 2))
    f_mag = rng.uniform(*false_magnitudes, n_f)
    uv = np.vstack([uv, f_uv])
    mags = np.concatenate([mags, f_mag])
    truth = np.concatenate([idx, np.full(n_f, FALSE_STAR)]).astype(np.int64)
    order = np.argsort(mags, kind="stable")
    return Frame(uv[order], mags[order], truth[order], np.asarray(attitude, dtype=float))
