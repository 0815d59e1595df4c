"""Orbits: truth propagation (Kepler, Cowell with J2 or a zonal geopotential, relative motion, SGP4 from a TLE),
frames and angles, station passes and the batch orbit fit; the truth source node kind."""
