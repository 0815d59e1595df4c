"""Station visibility: look angles, elevation series and pass (rise/set) finding.

Look angles follow paper 000 eqs. 8-14 in the local ENU frame of the station (frames.enu_rotation),
with the radar azimuth convention atan2(east, north), clockwise from north, in [0, 2 pi).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from scipy.optimize import brentq

from .constants import J2_EARTH, MU_EARTH, R_EARTH
from .cowell import propagate
from .frames import eci_to_ecef, enu_rotation, geodetic_to_ecef


class Pass(NamedTuple):
    """One visibility window above an elevation mask (times in s since epoch)."""

    t_rise: float
    t_set: float
    max_elevation: float

    @property
    def duration(self) -> float:
        """Time above the mask [s]."""
        return self.t_set - self.t_rise


def look_angles(
    times: np.ndarray,
    states_eci: np.ndarray,
    station_lat: float,
    station_lon: float,
    station_h: float,
    theta0: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Range [m], azimuth [rad, 0..2pi, clockwise from north] and elevation [rad] of ECI states.

    times (K,) and states_eci (K, 6) or (K, 3) (only positions are used); the station is given by
    WGS84 geodetic latitude, longitude [rad] and height [m] on the rotating Earth.
    """
    r_ecef = eci_to_ecef(np.asarray(states_eci, dtype=float)[..., 0:3], times, theta0)
    enu = (r_ecef - geodetic_to_ecef(station_lat, station_lon, station_h)) @ enu_rotation(station_lat, station_lon).T
    rng = np.linalg.norm(enu, axis=-1)
    az = np.mod(np.arctan2(enu[..., 0], enu[..., 1]), 2.0 * np.pi)
    el = np.arcsin(enu[..., 2] / rng)
    return rng, az, el


def elevation_series(
    times: np.ndarray,
    states_eci: np.ndarray,
    station_lat: float,
    station_lon: float,
    station_h: float,
    theta0: float = 0.0,
) -> np.ndarray:
    """Elevation [rad] of the ECI states (K, 6) seen from the station at the given times (K,)."""
    return look_angles(times, states_eci, station_lat, station_lon, station_h, theta0)[2]


def visibility_windows(
    times: np.ndarray, elevations: np.ndarray, min_elevation_rad: float
) -> list[tuple[float, float, float]]:
    """Windows (t_rise, t_set, max_elevation) where elevation >= the mask.

    Rise and set times are linearly interpolated between samples; a window already open at the first
    sample (or still open at the last) is clipped to the ends of the series.
    """
    times = np.asarray(times, dtype=float)
    elevations = np.asarray(elevations, dtype=float)
    above = elevations - min_elevation_rad
    up = above >= 0.0
    edges = np.flatnonzero(np.diff(up.astype(np.int8)))

    def crossing(k: int) -> float:
        return float(times[k] - above[k] * (times[k + 1] - times[k]) / (above[k + 1] - above[k]))

    rises = [float(times[0])] if up[0] else []
    sets = []
    for k in edges:
        (sets if up[k] else rises).append(crossing(k))
    if up[-1]:
        sets.append(float(times[-1]))
    windows = []
    for t_rise, t_set in zip(rises, sets):
        inside = (times >= t_rise) & (times <= t_set)
        windows.append((t_rise, t_set, float(np.max(elevations[inside]))))
    return windows


def _first_window(up: np.ndarray) -> tuple[int, int] | None:
    """Sample indices (k0, k1) bracketing the first rise (k0 below, k0 + 1 above the mask) and the set after it
    (k1 above, k1 + 1 below); None when no pass starts and ends within the samples."""
    rise_idx = np.flatnonzero(~up[:-1] & up[1:])
    if rise_idx.size == 0:
        return None
    k0 = int(rise_idx[0])
    set_after = np.flatnonzero(up[k0 + 1 : -1] & ~up[k0 + 2 :])
    if set_after.size == 0:
        return None
    return k0, k0 + 1 + int(set_after[0])


def find_pass(
    state0: np.ndarray,
    station_lat: float,
    station_lon: float,
    station_h: float,
    theta0: float,
    min_elevation: float,
    search_duration: float,
    step: float = 10.0,
    mu: float = MU_EARTH,
    j2: float = J2_EARTH,
    re: float = R_EARTH,
) -> Pass | None:
    """First pass of the satellite (ECI state0 at t = 0) over the station within search_duration.

    The orbit is sampled every ``step`` seconds to bracket the pass, then rise and set are refined
    with Brent's method on the Cowell-propagated elevation and the peak by a 0.1 s resampling.
    Returns None if no pass starts within the search interval (a pass open at t = 0 is skipped).
    """
    times = np.arange(0.0, search_duration + step, step)
    states = propagate(state0, times, mu, j2, re)
    el = elevation_series(times, states, station_lat, station_lon, station_h, theta0)
    window = _first_window(el >= min_elevation)
    if window is None:
        return None
    k0, k1 = window

    def excess(t: float, k: int) -> float:
        s = propagate(states[k], np.array([times[k], t]), mu, j2, re)[-1:]
        return float(elevation_series(np.array([t]), s, station_lat, station_lon, station_h, theta0)[0]) - min_elevation

    t_rise = brentq(excess, times[k0], times[k0 + 1], args=(k0,), xtol=1e-6)
    t_set = brentq(excess, times[k1], times[k1 + 1], args=(k1,), xtol=1e-6)
    fine_t = np.arange(times[k0], times[k1 + 1], 0.1)
    fine_el = elevation_series(
        fine_t, propagate(states[k0], fine_t, mu, j2, re), station_lat, station_lon, station_h, theta0
    )
    return Pass(float(t_rise), float(t_set), float(np.max(fine_el)))


def first_pass(
    trajectory: Callable[[np.ndarray], np.ndarray],
    station_lat: float,
    station_lon: float,
    station_h: float,
    theta0: float,
    min_elevation: float,
    search_duration: float,
    step: float = 10.0,
) -> Pass | None:
    """First pass over the station within search_duration of a trajectory given as a function of time:
    ``trajectory(times)`` -> ECI states (K, 6) at times [s] (e.g. orbit_sim.tle.ElementSet.states, SGP4).

    As :func:`find_pass`: sampled every ``step`` seconds to bracket the pass, rise and set refined by Brent's
    method to 1 µs, the peak from a 0.1 s resampling; None if no pass starts and ends within the search.
    """
    times = np.arange(0.0, search_duration + step, step)
    el = elevation_series(times, trajectory(times), station_lat, station_lon, station_h, theta0)
    window = _first_window(el >= min_elevation)
    if window is None:
        return None
    k0, k1 = window

    def excess(t: float) -> float:
        at = np.array([t])
        return (
            float(elevation_series(at, trajectory(at), station_lat, station_lon, station_h, theta0)[0]) - min_elevation
        )

    t_rise = brentq(excess, times[k0], times[k0 + 1], xtol=1e-6)
    t_set = brentq(excess, times[k1], times[k1 + 1], xtol=1e-6)
    fine_t = np.arange(times[k0], times[k1 + 1], 0.1)
    fine_el = elevation_series(fine_t, trajectory(fine_t), station_lat, station_lon, station_h, theta0)
    return Pass(float(t_rise), float(t_set), float(np.max(fine_el)))
