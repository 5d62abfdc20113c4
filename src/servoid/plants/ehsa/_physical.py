"""From a discrete plant to K, ω_hp, δ_hp: d2c, factorisation, flags (spec §3.4).

The continuous plant from the Tustin d2c is normalised (monic
denominator); the pole nearest s = 0 is the integrator s₀, the next pole
(and its conjugate, or the next real pole) the hydraulic pair
``s² + 2δω·s + ω²``; ``K = b₀/a₁`` (numerator constant over the s¹
coefficient), which is the velocity gain ``lim s·G0(s)`` whatever other
poles the model has. Uncertainty comes from the delta method: central
differences of the map along the principal axes of the source covariance.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..._errors import ModelError, ServoidWarning
from ..._warn import warn
from ...estimate import Estimate
from ...models import TransferFunction, d2c
from ._loop import PARAMETER_NAMES, PARAMETER_UNITS, FeedbackLoop, tustin_inverse
from ._result import ClosedLoopResult, PoleInfo

__all__: list[str] = []

#: Im/|p| below which a pole counts as real.
_REAL_TOL = 1e-7


@dataclass(frozen=True)
class _Anchors:
    """Nominal poles that define the roles, followed under perturbation."""

    integrator: complex
    pair: tuple[complex, complex] | None
    roles: tuple[str, ...]  # per pole of the nominal continuous plant
    poles: NDArray[np.complex128]


def to_continuous(plant: TransferFunction) -> TransferFunction:
    """Return the Tustin d2c of a discrete plant, with a clear error."""
    try:
        return d2c(plant, "tustin")
    except ModelError as exc:
        raise ModelError(
            f"{exc}. The identified plant has a pole at z = -1; lower na or check the data rate"
        ) from None


def anchors_of(plant_c: TransferFunction, cancel_tol: float | None) -> _Anchors:
    """Assign integrator / hydraulic / extra / cancelled roles to the poles."""
    poles = plant_c.poles()
    zeros = plant_c.zeros()
    roles = ["extra"] * poles.size
    if cancel_tol is not None and zeros.size:
        for i, p in enumerate(poles):
            if np.min(np.abs(zeros - p)) <= cancel_tol * max(1.0, abs(p)):
                roles[i] = "cancelled"
    free = [i for i in range(poles.size) if roles[i] != "cancelled"]
    if not free:
        raise ModelError("every pole of the plant is cancelled by a zero; nothing to factorise")
    free.sort(key=lambda i: abs(poles[i]))
    i0 = free.pop(0)
    roles[i0] = "integrator"
    pair: tuple[complex, complex] | None = None
    if free:
        i1 = free.pop(0)
        p1 = poles[i1]
        if abs(p1.imag) > _REAL_TOL * abs(p1) and free:
            i2 = min(free, key=lambda i: abs(poles[i] - np.conj(p1)))
        else:
            reals = [i for i in free if abs(poles[i].imag) <= _REAL_TOL * abs(poles[i])]
            i2 = reals[0] if reals else (free[0] if free else -1)
        if i2 >= 0:
            roles[i1] = roles[i2] = "hydraulic"
            pair = (complex(p1), complex(poles[i2]))
    return _Anchors(complex(poles[i0]), pair, tuple(roles), poles)


def values_of(plant_c: TransferFunction, anchors: _Anchors) -> NDArray[np.float64]:
    """Return (K, ω_hp, δ_hp, s₀) of a continuous plant."""
    den = plant_c.den
    roots = np.roots(den)
    taken: set[int] = set()

    def nearest(target: complex) -> complex:
        order = np.argsort(np.abs(roots - target))
        j = next(int(k) for k in order if int(k) not in taken)
        taken.add(j)
        return complex(roots[j])

    s0 = nearest(anchors.integrator).real
    omega = delta = math.nan
    if anchors.pair is not None:
        q1, q2 = nearest(anchors.pair[0]), nearest(anchors.pair[1])
        beta, gamma = -(q1 + q2).real, (q1 * q2).real
        if gamma > 0:
            omega = math.sqrt(gamma)
            delta = beta / (2.0 * omega)
    a1 = den[-2] if den.size >= 2 else math.nan
    k = float(plant_c.num[-1] / a1) if a1 != 0 else math.nan
    return np.array([k, omega, delta, s0])


def delta_method(
    fun: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    theta: NDArray[np.float64],
    cov: NDArray[np.float64],
    step: float,
) -> NDArray[np.float64]:
    """Propagate ``cov`` through ``fun`` by central differences.

    The differences run along the principal axes of ``cov`` with a step of
    ``step`` standard deviations, so strongly correlated ARX coefficients
    are moved only in directions the data allow (a coordinate step would
    leave the region where the map is linear).
    """
    lam, vec = np.linalg.eigh((cov + cov.T) / 2.0)
    f0 = fun(theta)
    out = np.zeros((f0.size, f0.size))
    for k in range(lam.size):
        if lam[k] <= 0.0:
            continue
        d = step * math.sqrt(lam[k]) * vec[:, k]
        g = (fun(theta + d) - fun(theta - d)) / (2.0 * step)
        out += np.outer(g, g)
    return out


def pole_report(
    closed_loop: TransferFunction | None,
    plant: TransferFunction,
    plant_c: TransferFunction,
    anchors: _Anchors,
    s0: float,
    s0_std: float,
    integrator_tol: float,
) -> tuple[PoleInfo, ...]:
    """Return every pole with its physical flag and explanation."""
    dt = plant.dt
    assert dt is not None
    nyquist = math.pi / dt
    out: list[PoleInfo] = []
    for z in closed_loop.poles() if closed_loop is not None else ():
        note = ""
        if abs(z) >= 1.0:
            note = (
                f"closed-loop pole z = {_c(z)} (|z| = {abs(z):.6g}) is outside the unit circle: the "
                "identified closed loop is unstable, yet the record comes from a running loop. "
                "The estimate is wrong (orders, delay, offsets or drift), or the loop really "
                "was unstable during the test"
            )
        elif _negative_real(z):
            note = _artefact(z, "closed-loop")
        out.append(PoleInfo(complex(z), "closed loop", "discrete", "closed loop", not note, note))
    for z in plant.poles():
        note = _artefact(z, "plant") if _negative_real(z) else ""
        out.append(PoleInfo(complex(z), "plant", "discrete", _role_d(z, dt, anchors), not note,
                            note))
    for p, role in zip(anchors.poles, anchors.roles, strict=True):
        note = ""
        if role == "integrator":
            limit = max(integrator_tol, 3.0 * s0_std) if np.isfinite(s0_std) else integrator_tol
            if abs(p.imag) > _REAL_TOL * abs(p):
                note = (
                    f"the pole nearest s = 0 is complex ({_c(p)} rad/s): the plant shows no "
                    "integrator, which an actuator with position output must have"
                )
            elif abs(s0) > limit:
                note = (
                    f"the plant's integrator came out at s0 = {s0:.4g} rad/s (± {s0_std:.2g}), "
                    f"not within {limit:.3g} rad/s of 0: the ARX structure misses it (the Tustin "
                    "image of a strictly proper 3rd-order plant needs nb = na + 1 = 4 with "
                    "nk = 0) or noise biases the ARX fit; refine with "
                    "approach='one-step', which fixes the integrator"
                )
        elif abs(p) >= nyquist:
            note = (
                f"pole s = {_c(p)} rad/s lies beyond the Nyquist frequency π/dt = {nyquist:.4g} "
                "rad/s: dynamics this fast cannot be resolved at this rate; read it "
                "as an artefact of unresolvable fast dynamics"
            )
        elif role == "hydraulic" and p.real >= 0.0:
            note = (
                f"hydraulic pole s = {_c(p)} rad/s is unstable or undamped: the reduced model "
                "needs a damped pair; check c and F and the model orders"
            )
        out.append(PoleInfo(complex(p), "plant", "continuous", role, not note, note))  # type: ignore[arg-type]
    return tuple(out)


def warn_flagged(poles: tuple[PoleInfo, ...]) -> None:
    """Issue one ServoidWarning per flagged pole."""
    for p in poles:
        if not p.is_physical:
            warn(p.note, ServoidWarning)


def two_step_result(
    approach: str,
    source: Estimate,
    closed_loop: TransferFunction | None,
    plant_of: Callable[[NDArray[np.float64]], TransferFunction],
    loop: FeedbackLoop | None,
    *,
    integrator_tol: float,
    cancel_tol: float | None,
    step: float,
) -> ClosedLoopResult:
    """Factorise a discrete plant from a linear fit; propagate its covariance."""
    theta = np.asarray(source.parameters, dtype=float)
    plant = plant_of(theta)
    plant_c = to_continuous(plant)
    anchors = anchors_of(plant_c, cancel_tol)

    def fun(t: NDArray[np.float64]) -> NDArray[np.float64]:
        return values_of(tustin_inverse(plant_of(t)), anchors)

    values = values_of(plant_c, anchors)
    cov4 = delta_method(fun, theta, np.asarray(source.covariance), step)
    s0, s0_std = float(values[3]), float(math.sqrt(max(cov4[3, 3], 0.0)))
    estimate = Estimate(
        model=plant_c,
        parameters=values[:3],
        names=PARAMETER_NAMES,
        covariance=cov4[:3, :3],
        noise_variance=source.noise_variance,
        n_samples=source.n_samples,
        method=approach,
        status=source.status,
        options={**dict(source.options), "delta_method_step": step},
        units=PARAMETER_UNITS,
        residual_function=source.residual_function,
    )
    poles = pole_report(closed_loop, plant, plant_c, anchors, s0, s0_std, integrator_tol)
    warn_flagged(poles)
    return ClosedLoopResult(
        approach, estimate, closed_loop, plant, plant_c, poles, loop, s0, s0_std, source
    )


def _negative_real(z: complex) -> bool:
    return z.real < 0.0 and abs(z.imag) <= 1e-6 * max(abs(z), 1e-12)


def _artefact(z: complex, which: str) -> str:
    return (
        f"{which} pole z = {_c(z)} is negative real: it has no ZOH preimage and by Tustin maps "
        "beyond the Nyquist frequency, a typical ARX artefact of unresolvable fast dynamics; "
        "treat it as non-physical"
    )


def _role_d(z: complex, dt: float, anchors: _Anchors) -> str:
    # discrete plant poles map one to one (Tustin) onto the continuous ones
    k = 2.0 / dt
    if abs(z + 1.0) < 1e-15:
        return "extra"
    s = k * (z - 1.0) / (z + 1.0)
    j = int(np.argmin(np.abs(anchors.poles - s)))
    return anchors.roles[j]


def _c(x: complex) -> str:
    x = complex(x)
    if abs(x.imag) <= _REAL_TOL * max(abs(x), 1e-300):
        return f"{x.real:.6g}"
    return f"{x.real:.6g}{x.imag:+.6g}j"
