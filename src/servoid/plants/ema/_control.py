"""The EMA's loop: a sampled drive with current, speed and position loops.

Every ``dt`` (the simulator's sample period) the drive reads the motor
current, the encoder and the load position, and writes a motor voltage
that the power stage holds until the next sample (zero-order hold, no
computation delay)::

    every outer_every samples (the outer loops, period T_o = outer_every·dt):
        ω̂     = (θ̂(k) − θ̂(k − outer_every)) / T_o        encoder backward difference
        ω_ref = sat(kp_x·e_x + z_x, w_max),   e_x = r(k) − x̂(k)
        i_ref = sat(kp_w·e_w + z_w, i_max),   e_w = ω_ref − ω̂
    every sample:
        u     = sat(kp_i·e_i + z_i, u_max),   e_i = i_ref − î(k)

Each integrator adds ``k_i·e·T`` after its output is computed, unless the
output is saturated and the error would drive it further (conditional
integration, the anti-windup of most drives).  ``θ̂`` is the encoder
angle, ``floor(θ·counts/2π)·2π/counts``; ``x̂`` the load position from the
LVDT (``feedback = "load"``) or the nut position from the encoder
(``"motor"``); ``î`` the current sensor.  Sensor noise, if any, is the
simulator's ``measurement_noise``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ..._errors import ModelError, OptionTypeError, check_option
from ._checks import Bounds, check_fields

__all__ = ["FEEDBACKS", "TVC_CONTROLLER", "EmaController", "Feedback"]

Feedback = Literal["load", "motor"]
FEEDBACKS: tuple[Feedback, ...] = ("load", "motor")

_BOUNDS: Bounds = {
    "kp_i": (0.0, True, False), "ki_i": (0.0, False, False),
    "kp_w": (0.0, True, False), "ki_w": (0.0, False, False),
    "kp_x": (0.0, True, False), "ki_x": (0.0, False, False),
    "u_max": (0.0, True, True), "i_max": (0.0, True, True), "w_max": (0.0, True, True),
}


@dataclass(frozen=True)
class EmaController:
    """Cascaded current, speed and position loops of a sampled drive.

    Defaults are :data:`TVC_CONTROLLER`, tuned for
    :data:`~servoid.plants.ema.TVC_EMA` at a 10 kHz drive (module notes
    give the law).

    Parameters
    ----------
    kp_i : float
        Current-loop gain [V/A].  6: a 640 Hz current loop with the 1.5 mH
        winding (``kp_i/L`` = 4000 rad/s).
    ki_i : float
        Current-loop integral gain [V/(A·s)].  1600: ``kp_i·R/L``, the
        zero on the winding's pole.
    kp_w : float
        Speed-loop gain [A·s/rad].  0.43: a 30 Hz speed loop on the total
        inertia at the motor (``kp_w·K_m/J`` = 190 rad/s).
    ki_w : float
        Speed-loop integral gain [A/rad].  16: its zero at 37 rad/s.
    kp_x : float
        Position-loop gain, speed reference per position error
        [(rad/s)/m].  1.42e5: a 6 Hz position loop (38 rad/s times the
        3770 rad/m transmission).
    ki_x : float
        Position-loop integral gain [(rad/s)/(m·s)]; 0 (default) makes
        the position loop a P loop.
    u_max : float
        Voltage limit [V] (``inf``: none).  270, the MIL-STD-704F DC bus.
    i_max : float
        Current limit [A] (``inf``: none).  40 (30 kN at the screw).
    w_max : float
        Speed limit [rad/s] (``inf``: none).  900 (0.24 m/s at the nut).
    outer_every : int
        The speed and position loops run every ``outer_every`` samples.
        Default 1.
    encoder_counts : int
        Encoder counts per motor revolution (0: an exact angle).  65536
        (16 bit).
    feedback : {"load", "motor"}
        Position the position loop reads: the load (LVDT) or the nut
        from the encoder.  Default "load".
    """

    kp_i: float = 6.0
    ki_i: float = 1600.0
    kp_w: float = 0.43
    ki_w: float = 16.0
    kp_x: float = 1.42e5
    ki_x: float = 0.0
    u_max: float = 270.0
    i_max: float = 40.0
    w_max: float = 900.0
    outer_every: int = 1
    encoder_counts: int = 65536
    feedback: Feedback = "load"

    def __post_init__(self) -> None:
        check_fields(self, _BOUNDS)
        for name, low in (("outer_every", 1), ("encoder_counts", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise OptionTypeError(f"EmaController.{name} must be an integer, got {value!r}")
            if value < low:
                raise ModelError(f"EmaController.{name} must be >= {low}, got {value}")
            object.__setattr__(self, name, int(value))
        check_option("EmaController.feedback", self.feedback, FEEDBACKS)

    def packed(self) -> NDArray[np.float64]:
        """Gains and limits as the kernel reads them."""
        return np.array([self.kp_i, self.ki_i, self.kp_w, self.ki_w, self.kp_x, self.ki_x,
                         self.u_max, self.i_max, self.w_max, float(self.encoder_counts),
                         1.0 if self.feedback == "load" else 0.0])

    def to_dict(self) -> dict[str, float | int | str]:
        """The loop as plain data (the ``[loop]`` table of an experiment file)."""
        out: dict[str, float | int | str] = {}
        for name in ("kp_i", "ki_i", "kp_w", "ki_w", "kp_x", "ki_x", "u_max", "i_max", "w_max"):
            value = getattr(self, name)
            out[name] = value if math.isfinite(value) else "inf"
        out.update(outer_every=self.outer_every, encoder_counts=self.encoder_counts,
                   feedback=self.feedback)
        return out


#: The drive of the nominal TVC EMA (values and reasons: :class:`EmaController`).
TVC_CONTROLLER = EmaController()
