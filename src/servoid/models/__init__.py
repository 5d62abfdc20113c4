"""LTI models: polynomial (ARX … BJ), transfer functions and state space.

Continuous models have ``dt=None``; discrete ones have ``dt`` [s] and
remember how they were discretised (``method``, ``prewarp``).  :func:`c2d`
and :func:`d2c` convert both ways (ZOH, Tustin); :func:`to_scipy`,
:func:`from_scipy`, :func:`to_control` and :func:`from_control` talk to
scipy.signal and python-control.
"""

from ._discretize import c2d, d2c
from ._interop import from_control, from_scipy, to_control, to_scipy
from ._polynomial import PolynomialModel
from ._response import TimeResponse
from ._statespace import StateSpace
from ._transfer import TransferFunction

__all__ = [
    "PolynomialModel",
    "StateSpace",
    "TimeResponse",
    "TransferFunction",
    "c2d",
    "d2c",
    "from_control",
    "from_scipy",
    "to_control",
    "to_scipy",
]
