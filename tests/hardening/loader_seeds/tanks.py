"""Two tanks in cascade, fed by a pump: the grey-box model servoid fits.

A pump driven by u [V] fills the upper tank (level h1 [m]), which drains
through an orifice into the lower tank (level h2 [m]), which drains to a
sump.  Torricelli's law gives each outflow, a·√(2·g·h).  The upper tank
overflows at its rim and the pump saturates: both are declared in the
experiment file ([identify.saturation]), not written here.

Parameters p, in the order of [identify.parameters]: k [m³/(s·V)] pump
gain, a1 and a2 [m²] effective orifice areas, A [m²] tank cross-section.
"""

import math

G = 9.81  # [m/s²]


def rhs(x, u, p):
    """dx/dt of the levels (h1, h2) under the pump voltage u[0]."""
    k, a1, a2, area = p[0], p[1], p[2], p[3]
    q12 = a1 * math.sqrt(2.0 * G * max(x[0], 0.0))
    q2 = a2 * math.sqrt(2.0 * G * max(x[1], 0.0))
    return ((k * u[0] - q12) / area, (q12 - q2) / area)


def level(x, u, p):
    """The measured output: the lower tank's level h2 [m]."""
    return x[1]
