"""Physical constants and unit conversions used throughout fdml (SI inside).

All of fdml works in SI units and radians; accelerations ``az`` are in units of
standard gravity (docs/theory.md Eq. 5).  The factors below are exact by definition
(NIST SP 811), so converting a record loses nothing.
"""

from __future__ import annotations

import math

#: Standard gravity, m/s^2 (exact, CGPM 1901).  a_z is expressed in units of G0.
G0 = 9.80665
#: One foot in metres (exact).
FT = 0.3048
#: One pound-mass in kilograms (exact).
LB = 0.45359237
#: One pound-force in newtons (exact: LB * G0).
LBF = LB * G0
#: One slug in kilograms (lbf s^2 / ft).
SLUG = LBF / FT
#: One degree in radians.
DEG = math.pi / 180.0
#: One knot in m/s (exact).
KNOT = 1852.0 / 3600.0

__all__ = ["G0", "FT", "LB", "LBF", "SLUG", "DEG", "KNOT"]
