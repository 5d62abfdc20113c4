"""One integrator: the compiled fixed-step RK4 step every simulator takes.

Every simulator in servoid — the electro-hydraulic, servopneumatic and
rigid-axis kernels and a user's grey-box ODE — advances its state with
:func:`rk4_step`, built from its right-hand side and a post-step hook
(end stops, stiction, saturations).  See :mod:`._rk4`.
"""

from ._rk4 import advance, keep, rk4_step

__all__ = ["advance", "keep", "rk4_step"]
