"""Units of the field, to SI: one home for each conversion factor (issue 23).

A value in the named unit times the factor is SI (rad, rad/s, m/s^2, dimensionless); divide to go back.
Standard gravity here is a unit (the g of "mg", "micro-g"), not the navigation's gravity model
(:func:`sinscli.nav.earth.gravity`, docs/formats.md normal gravity).  No imports beyond :mod:`math`, so that every
layer (and the command line's option lists) can use it.
"""
import math

G0 = 9.80665                    # m/s^2 per g: standard gravity (CGPM 1901)
MG = 1e-3 * G0                  # m/s^2 per milli-g
UG = 1e-6 * G0                  # m/s^2 per micro-g (the sensor descriptions' unit; equals 9.80665e-6 within 1 ulp)
DEG = math.pi / 180.0           # rad per degree
ARCSEC = DEG / 3600.0           # rad per arcsecond
DEG_PER_H = DEG / 3600.0        # rad/s per deg/h (gyro bias)
DEG_PER_SQRT_H = DEG / 60.0     # rad/sqrt(s) per deg/sqrt(h) (angle random walk)
PPM = 1e-6                      # per part per million (scale factor)
