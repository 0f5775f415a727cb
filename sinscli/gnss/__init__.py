"""Raw GNSS: broadcast orbits and clocks, corrections, measurement models and single-point positioning.

Numerical kernels only (no I/O): ``orbits`` (satellite position, velocity and clock from broadcast
ephemerides), ``corrections`` (Klobuchar, Saastamoinen, mapping function), ``model`` (geometric range
with the Sagnac term, predicted pseudorange and range rate, the design rows), ``spp`` (weighted least
squares, Doppler velocity, fault detection and exclusion).  ``ephemeris`` is the one table the RINEX and
UBX readers fill; ``signals`` the systems, bands and frequencies; ``timesys`` GPS time.
See docs/raw_gnss.md.
"""
