"""Table 1 of the paper (the trailers and the sampling time of its simulations and experiments).

The one place these numbers are written. The FMU's variable table and its C defaults, the
scenario's defaults, the chain geometry's and the controller's defaults and the docs read them
from here. Units: SI.
"""

from __future__ import annotations

__all__ = [
    "LINK",
    "MU",
    "SAMPLING_TIME",
    "STATIC_FRICTION_FORCE",
    "TRAILER_INERTIA",
    "TRAILER_LENGTH",
    "TRAILER_MASS",
    "TRAILER_WIDTH",
]

TRAILER_MASS = 42.1
"""Mass of one trailer without payload [kg]."""

LINK = 0.52
"""Link length D, hitch to axle, of every trailer (front and rear) [m]."""

TRAILER_LENGTH = 0.8
"""Trailer body length along its heading [m] (Table 1: 0.6 m x 0.8 m)."""

TRAILER_WIDTH = 0.6
"""Trailer body width across its heading [m]."""

TRAILER_INERTIA = round(TRAILER_MASS * (TRAILER_LENGTH**2 + TRAILER_WIDTH**2) / 12.0, 4)
"""Centroidal yaw inertia of the trailer body as a uniform plate, m (a^2 + b^2) / 12, rounded to
0.1 g m^2 as the FMU has always published it [kg m^2] (3.5083)."""

MU = 0.09
"""Lateral wheel friction coefficient."""

SAMPLING_TIME = 0.005
"""Sampling time of the controller and of the co-simulation's communication step [s]."""

STATIC_FRICTION_FORCE = 37.2
"""Measured static lateral friction force of the first trailer's wheels [N] (Section 4.4)."""
