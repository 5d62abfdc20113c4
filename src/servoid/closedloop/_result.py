"""Typed results of the closed-loop approaches: poles and the physical estimate."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

from ..estimate import Estimate
from ..models import TransferFunction
from ._loop import FeedbackLoop

__all__ = ["ClosedLoopResult", "PoleInfo"]

PoleModel = Literal["closed loop", "plant"]
Domain = Literal["discrete", "continuous"]
Role = Literal["integrator", "hydraulic", "extra", "cancelled", "closed loop"]


@dataclass(frozen=True)
class PoleInfo:
    """One pole with its physical reading.

    Parameters
    ----------
    value : complex
        The pole: z (discrete) or s [rad/s] (continuous).
    model : {"closed loop", "plant"}
        Which transfer function it belongs to.
    domain : {"discrete", "continuous"}
        z-plane or s-plane.
    role : {"integrator", "hydraulic", "extra", "cancelled", "closed loop"}
        Its place in the reduced model (``"closed loop"`` for poles of H).
    is_physical : bool
        False when the pole cannot belong to the actuator (see `note`).
    note : str
        Why a pole is flagged, empty when it is not.
    """

    value: complex
    model: PoleModel
    domain: Domain
    role: Role
    is_physical: bool
    note: str = ""

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form for JSON (complex as real and imaginary parts)."""
        return {
            "real": float(self.value.real),
            "imag": float(self.value.imag),
            "model": self.model,
            "domain": self.domain,
            "role": self.role,
            "is_physical": self.is_physical,
            "note": self.note,
        }


@dataclass(frozen=True, eq=False)
class ClosedLoopResult:
    """Physical parameters of the plant identified inside its loop.

    Parameters
    ----------
    approach : str
        ``"indirect"``, ``"one-step"`` or ``"direct"``.
    estimate : Estimate
        K [1/s], omega_hp [rad/s], delta_hp [-] with covariance.
    closed_loop : TransferFunction or None
        Discrete closed loop H from r to y (None: direct without a loop).
    plant : TransferFunction
        Discrete plant G0 (Tustin image).
    plant_continuous : TransferFunction
        Continuous plant from the Tustin d2c.
    poles : tuple of PoleInfo
        Poles of H (discrete), G0 (discrete) and G0 (continuous).
    loop : FeedbackLoop or None
        The known loop (c, F); None for a direct fit without one.
    integrator : float
        Pole of G0(s) taken as the integrator s₀ [rad/s] (0 in a model).
    integrator_std : float
        Its standard deviation [rad/s] (0 when the structure fixes it).
    source : Estimate
        The estimate behind the result (ARX or output-error fit).
    """

    approach: str
    estimate: Estimate
    closed_loop: TransferFunction | None
    plant: TransferFunction
    plant_continuous: TransferFunction
    poles: tuple[PoleInfo, ...]
    loop: FeedbackLoop | None
    integrator: float
    integrator_std: float
    source: Estimate

    @property
    def is_physical(self) -> bool:
        """True when no pole is flagged non-physical."""
        return all(p.is_physical for p in self.poles)

    @property
    def dt(self) -> float:
        """Sample period of the discrete models [s]."""
        assert self.plant.dt is not None
        return self.plant.dt

    def parameters(self) -> dict[str, float]:
        """Return K, omega_hp and delta_hp by name."""
        return {n: float(v) for n, v in zip(self.estimate.names, self.estimate.parameters)}

    def notes(self) -> list[str]:
        """Return the explanations of every flagged pole."""
        return [p.note for p in self.poles if not p.is_physical]

    def to_dict(self, level: float = 0.95) -> dict[str, Any]:
        """Plain-data summary for JSON.

        Parameters
        ----------
        level : float
            Confidence level of the parameter intervals.
        """

        def tf(g: TransferFunction | None) -> dict[str, Any] | None:
            if g is None:
                return None
            return {"num": g.num.tolist(), "den": g.den.tolist(), "dt": g.dt}

        return {
            "approach": self.approach,
            "loop": None if self.loop is None else self.loop.to_dict(),
            "estimate": self.estimate.to_dict(level),
            "integrator": self.integrator,
            "integrator_std": self.integrator_std,
            "is_physical": self.is_physical,
            "closed_loop": tf(self.closed_loop),
            "plant": tf(self.plant),
            "plant_continuous": tf(self.plant_continuous),
            "poles": [p.to_dict() for p in self.poles],
            "source": {"method": self.source.method, "options": dict(self.source.options)},
        }

    def __str__(self) -> str:
        lines = [f"closed-loop identification, {self.approach} approach", str(self.estimate)]
        lines.append(f"  integrator s0 = {self.integrator:.4g} ± {self.integrator_std:.2g} rad/s")
        lines += [f"  ! {note}" for note in self.notes()]
        return "\n".join(lines)

