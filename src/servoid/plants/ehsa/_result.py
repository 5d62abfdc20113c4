"""Typed results of the closed-loop approaches: poles and the physical estimate."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from ..._errors import DataError
from ...data import Experiment
from ...estimate import Estimate
from ...models import TransferFunction
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
        Discrete closed loop H from r to y as fitted (None: direct without
        a loop); ``y(k) = H(q)·r(k + advance)``. For a declared rig chain
        it includes the anti-alias filter and the decimation FIR.
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
    discretization : str
        How the continuous loop became discrete (``"tustin"`` for the
        two-step d2c; see :func:`~servoid.plants.ehsa.fit_one_step`).
    intersample : str
        The reference's course between samples the model assumes:
        ``"zoh"``, ``"foh"``, ``"bandlimited"``, or ``"none"`` for a map.
    intersample_note : str
        That assumption in words, with how it was chosen and what the
        reference looks like.
    advance : int
        Samples by which `closed_loop` looks ahead [samples], >= 0.
    flags : tuple of str
        What the data cannot resolve (the resonance beyond the rate, or
        not determined), each with the remedy; empty when nothing is.
    structure : str
        The plant structure fitted (``"reduced"``, …).
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
    discretization: str = "tustin"
    intersample: str = "none"
    intersample_note: str = ""
    advance: int = 0
    flags: tuple[str, ...] = ()
    structure: str = "reduced"

    @property
    def is_physical(self) -> bool:
        """True when no pole is flagged non-physical."""
        return all(p.is_physical for p in self.poles)

    @property
    def is_resolved(self) -> bool:
        """True when the data resolve the resonance (no flag)."""
        return not self.flags

    @property
    def dt(self) -> float:
        """Sample period of the discrete models [s]."""
        assert self.plant.dt is not None
        return self.plant.dt

    def parameters(self) -> dict[str, float]:
        """Return K, omega_hp and delta_hp by name."""
        return {n: float(v) for n, v in zip(self.estimate.names, self.estimate.parameters)}

    def notes(self) -> list[str]:
        """Return the explanations of every flagged pole, then the flags."""
        return [p.note for p in self.poles if not p.is_physical] + list(self.flags)

    def align(self, data: Experiment) -> Experiment:
        """Return the record as `closed_loop` simulates it causally.

        With ``advance = L > 0`` the pairs are ``(r(k), y(k − L))`` for
        k = L…N−1: the first L reference samples and the last L outputs
        drop out, and a simulation of `closed_loop` on the result needs
        its initial state estimated (``servoid.validate.validate(...,
        initial="estimate")``). With L = 0 the record is returned as is.

        Parameters
        ----------
        data : Experiment
            A record with the reference r and the output y.

        Returns
        -------
        Experiment
            The aligned record (same channels, names and units).
        """
        if not self.advance:
            return data
        n = data.n_samples
        if n <= 2 * self.advance:
            raise DataError(f"the record has {n} samples; aligning by advance = "
                            f"{self.advance} needs more than {2 * self.advance}")
        shifted = []
        for ch in data.channels:
            values = ch.values[self.advance:] if ch.role == "r" else ch.values[: n - self.advance]
            shifted.append(ch.with_values(np.asarray(values)))
        return data.replace_channels(shifted)

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
            "structure": self.structure,
            "discretization": self.discretization,
            "intersample": self.intersample,
            "intersample_note": self.intersample_note,
            "advance": self.advance,
            "flags": list(self.flags),
            "is_resolved": self.is_resolved,
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
        if self.intersample_note:
            lines.append(f"  intersample: {self.intersample_note}")
        lines += [f"  ! {note}" for note in self.notes()]
        return "\n".join(lines)

