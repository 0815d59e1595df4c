"""Physical constants (SI units) shared by the orbit models.

Values follow paper 000 (leo_radar, section 2) and WGS84. The paper prints
Re = 6378.173 km; that is a transposition typo for the WGS84 equatorial radius 6378.137 km used here.
"""

MU_EARTH: float = 3.986004418e14
"""Earth's gravitational parameter mu [m^3/s^2] (paper: 398600.4418 km^3/s^2)."""

R_EARTH: float = 6378137.0
"""Equatorial radius Re [m] (WGS84 semi-major axis; the paper's 6378.173 km is a typo)."""

J2_EARTH: float = 1.082626925638815e-3
"""Second zonal harmonic J2 [-] (paper: 1082.626925638815e-6)."""

OMEGA_EARTH: float = 7.2921150e-5
"""Earth rotation rate [rad/s]."""

WGS84_F: float = 1.0 / 298.257223563
"""WGS84 flattening f [-]."""

WGS84_E2: float = WGS84_F * (2.0 - WGS84_F)
"""WGS84 first eccentricity squared e^2 = f (2 - f) [-]."""
