"""Attitude truth of a star camera riding a circular orbit (the paper's 30°-inclination, 700 km orbit), fixed
in the local-vertical/local-horizontal (LVLH) frame, with the paper's boresight jitter.

Orbit: circular, radius R_E + h, inclination i, right ascension of the ascending node Ω, argument of latitude
u(t) = u0 + n t, with the mean motion n = √(μ/a³) (700 km: a period of 98.8 min; the paper rounds the orbit to
"one revolution per 90 minutes" — ``period_s`` overrides n if its number is wanted). In ICRS:

    r̂ = (cos Ω cos u − sin Ω sin u cos i,  sin Ω cos u + cos Ω sin u cos i,  sin u sin i)   radial (zenith)
    ĥ = (sin Ω sin i,  −cos Ω sin i,  cos i)                                                orbit normal
    t̂ = ĥ × r̂                                                                             along-track

The LVLH frame turns at n about ĥ, so a camera fixed in it sees the sky move in one of the paper's two ways:
- ``boresight="zenith"``: camera z = r̂, x = t̂, y = ĥ. The turn axis ĥ is across the boresight: the stars
  drift in straight lines at f·n px/s along −x (the paper's constant-velocity case; ~3.1 px/s for the
  default camera, 0.31 px per frame at 10 frames/s).
- ``boresight="normal"``: camera z = ĥ, x = r̂, y = t̂. The turn is about the boresight: the sky rotates
  about the image centre at −n (the paper's rotation case).
The camera-from-ICRS attitude has those axes as rows; the body rate (camera frame) is (0, n, 0) and (0, 0, n).

Jitter (paper, eq. 18 and its text): the camera turns about its boresight at a rate drawn uniformly in
[−J, J] (deg/s), held for ``hold`` consecutive frames (10 in the paper) and drawn afresh for the next block.
The jitter angle φ(t) (the integral of that rate) turns the camera about its own z axis relative to its LVLH
mount: A(t) = exp(−φ(t) [ẑ×]) A_LVLH(t), and the body rate is ω = exp(−φ [ẑ×]) ω_LVLH + φ̇ ẑ.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from orbit_sim.constants import MU_EARTH, R_EARTH
from star_tracker.options import BORESIGHTS


@dataclass(frozen=True)
class CircularOrbit:
    """A circular orbit (module docstring)."""

    altitude_m: float = 700e3
    inclination_deg: float = 30.0
    raan_deg: float = 0.0
    arg_latitude0_deg: float = 0.0
    period_s: float | None = None
    """None: the Keplerian period of the radius."""

    @property
    def mean_motion(self) -> float:
        """n (rad/s)."""
        if self.period_s is not None:
            return 2.0 * np.pi / self.period_s
        a = R_EARTH + self.altitude_m
        return float(np.sqrt(MU_EARTH / a**3))

    def axes(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """r̂, t̂, ĥ (each (K, 3), ICRS) at times t (K,) (s)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        i, raan = np.radians(self.inclination_deg), np.radians(self.raan_deg)
        u = np.radians(self.arg_latitude0_deg) + self.mean_motion * t
        r = np.column_stack(
            [
                np.cos(raan) * np.cos(u) - np.sin(raan) * np.sin(u) * np.cos(i),
                np.sin(raan) * np.cos(u) + np.cos(raan) * np.sin(u) * np.cos(i),
                np.sin(u) * np.sin(i),
            ]
        )
        h = np.broadcast_to([np.sin(raan) * np.sin(i), -np.cos(raan) * np.sin(i), np.cos(i)], r.shape).copy()
        return r, np.cross(h, r), h


def lvlh_attitude(orbit: CircularOrbit, t: np.ndarray, boresight: str = "zenith") -> tuple[np.ndarray, np.ndarray]:
    """Camera-from-ICRS attitudes (K, 3, 3) and body rates (K, 3) (rad/s, camera frame) of a camera fixed in
    LVLH (module docstring)."""
    r, tt, h = orbit.axes(t)
    n = orbit.mean_motion
    if boresight == "zenith":
        A, w = np.stack([tt, h, r], axis=1), [0.0, n, 0.0]
    elif boresight == "normal":
        A, w = np.stack([r, tt, h], axis=1), [0.0, 0.0, n]
    else:
        raise ValueError(f"boresight must be one of {BORESIGHTS}, got {boresight!r}")
    return A, np.broadcast_to(np.asarray(w, dtype=float), (len(A), 3)).copy()


def jitter_rates(n_frames: int, amplitude_deg_s: float, rng: np.random.Generator, hold: int = 10) -> np.ndarray:
    """(n_frames,) boresight jitter rate (rad/s) of each frame interval: uniform in ±J, held for ``hold``
    frames."""
    if hold < 1:
        raise ValueError(f"hold must be >= 1, got {hold}")
    blocks = rng.uniform(-1.0, 1.0, -(-n_frames // hold)) * np.radians(amplitude_deg_s)
    return np.repeat(blocks, hold)[:n_frames]


@dataclass
class AttitudeTruth:
    """Per-frame truth of a run: times, attitudes and body rates."""

    t: np.ndarray
    """(K,) frame times (s)."""
    attitude: np.ndarray
    """(K, 3, 3) camera-from-ICRS."""
    rate: np.ndarray
    """(K, 3) body rate at each frame (rad/s, camera frame)."""
    jitter_angle: np.ndarray
    """(K,) φ (rad)."""
    jitter_rate: np.ndarray
    """(K,) φ̇ (rad/s) over the interval from frame k to k + 1 (the boresight part of ``rate``)."""

    @property
    def quaternions(self) -> np.ndarray:
        """(K, 4) scalar-first quaternions of the attitudes (attitude.py convention, qw >= 0)."""
        q = Rotation.from_matrix(self.attitude).as_quat(scalar_first=True)
        return np.where(q[:, :1] < 0, -q, q)


def orbit_truth(
    orbit: CircularOrbit,
    n_frames: int,
    frame_dt: float,
    boresight: str = "zenith",
    jitter_deg_s: float = 0.0,
    rng: np.random.Generator | None = None,
    hold: int = 10,
) -> AttitudeTruth:
    """The attitude truth of ``n_frames`` frames every ``frame_dt`` s (module docstring). The jitter rate of
    frame interval k (between frames k and k + 1) is jitter_rates(...)[k]; frame 0 has φ = 0."""
    t = np.arange(n_frames) * frame_dt
    A, w = lvlh_attitude(orbit, t, boresight)
    if jitter_deg_s > 0:
        if rng is None:
            raise ValueError("jitter needs a random generator")
        rates = jitter_rates(n_frames, jitter_deg_s, rng, hold)
    else:
        rates = np.zeros(n_frames)
    phi = np.concatenate([[0.0], np.cumsum(rates[:-1] * frame_dt)])
    turn = Rotation.from_rotvec(-phi[:, None] * np.array([0.0, 0.0, 1.0])).as_matrix()  # exp(−φ[ẑ×])
    A = turn @ A
    w = np.einsum("kij,kj->ki", turn, w)
    w[:, 2] += rates
    return AttitudeTruth(t, A, w, phi, rates)
