"""A controller known only in continuous time: is its discretisation a guess the plant feels?

The indirect approach takes the controller as exact: with the loop
``Gcl = G·C/(1 + G·C)`` a controller ``C`` that differs from the one that
ran, ``C₀``, returns the plant ``G·C₀/C``, biased at each frequency by the
controller's own relative error ``C₀/C − 1``.  A controller given in
continuous time is discretised at the record's dt (Tustin by default), but
the digital loop may have run it as any discretisation of the design.
Far below the Nyquist frequency all of them agree; near it they do not
(zero-order hold, Tustin and first-order hold differ by the order of
``(ω·dt)²``, and far more where the design has poles or zeros near π/dt).

The data cannot tell which discretisation ran (the controller's error
only moves the plant), so :func:`discretisation_check` asks how much the
guess matters: the plant is fitted again with each other discretisation,
and when one of them moves a coefficient by more than one standard
deviation the estimate does not claim consistency.  A bias of one σ
already lowers a 95 % interval's coverage to about 83 %.  The verdict
names the frequency where the discretisations differ most relative to the
plant's own relative standard deviation (delta method on ``log G``), which
is where the controller is too fast for the sampling.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from ..models import TransferFunction, c2d

__all__ = ["DISCRETISATIONS", "discretisation_check"]

#: The discretisations a digital loop may have run a continuous design as.
DISCRETISATIONS = ("tustin", "zoh", "foh")
#: Largest move of a coefficient [its σ] under another discretisation that is claimed.
_MOVE = 1.0
#: Frequencies of the comparison, as fractions of the Nyquist frequency (log-spaced).
_GRID = np.geomspace(1e-3, 0.98, 240)


def discretisation_check(
    continuous: TransferFunction, used: str, dt: float, theta: NDArray[np.float64],
    covariance: NDArray[np.float64], nb: int, alternatives: Mapping[str, NDArray[np.float64]],
    names: Sequence[str],
) -> tuple[float, str | None]:
    """How far the plant moves under the other discretisations, and a verdict.

    Parameters
    ----------
    continuous : TransferFunction
        The controller as given, continuous (``dt=None``).
    used : str
        The discretisation the estimate used.
    dt : float
        The record's sample period [s].
    theta, covariance : ndarray
        The plant estimate (b0…, f1…) and its covariance.
    nb : int
        B coefficients of the plant.
    alternatives : mapping of str to ndarray
        The plant fitted with each other discretisation of the controller.
    names : sequence of str
        The coefficients' names.

    Returns
    -------
    move : float
        The largest ``|θ_m − θ̂|/σ`` over the coefficients and the other
        discretisations m (0 without alternatives).
    verdict : str or None
        Why the estimate cannot claim consistency, when ``move > 1``.
    """
    sigma = np.sqrt(np.maximum(np.diag(covariance), 1e-300))
    move, worst, coef = 0.0, "", ""
    for method, alt in alternatives.items():
        shift = np.abs(np.asarray(alt) - theta) / sigma
        k = int(np.argmax(shift))
        if float(shift[k]) > move:
            move, worst, coef = float(shift[k]), method, names[k]
    if not move > _MOVE:
        return move, None
    omega = _GRID * np.pi / dt
    z = np.exp(1j * omega * dt)
    base = _response(c2d(continuous, dt, used), z)  # type: ignore[arg-type]
    gap = np.abs(_response(c2d(continuous, dt, worst), z) / base - 1.0)  # type: ignore[arg-type]
    rel = _relative_sigma(theta, covariance, nb, omega * dt)
    k = int(np.argmax(gap / np.maximum(rel, 1e-300)))
    return move, (
        f"the controller was given in continuous time and discretised at the record's dt "
        f"= {dt:g} s by {used}, but its dynamics reach toward the Nyquist frequency "
        f"({0.5 / dt:.4g} Hz), where its discretisations part: the {worst} one differs from "
        f"it by {100 * gap[k]:.2g} % at {omega[k] / (2 * np.pi):.3g} Hz, and fitted with it "
        f"the plant's {coef} moves by {move:.3g} σ. The data cannot tell which one ran and the "
        "indirect approach takes the controller as exact; give the controller as it ran "
        "(discrete, at the record's dt), or use method = \"cliv\" or \"two-stage\", which "
        "need only the reference"
    )


def _response(tf: TransferFunction, z: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """A discrete transfer function's response at the points z (descending powers of z)."""
    return np.polyval(np.asarray(tf.num, dtype=float), z) / np.polyval(
        np.asarray(tf.den, dtype=float), z)


def _relative_sigma(theta: NDArray[np.float64], covariance: NDArray[np.float64], nb: int,
                    wdt: NDArray[np.float64]) -> NDArray[np.float64]:
    """σ of ``|ΔG/G|`` at each ω·dt, from the covariance of (b0…, f1…) (delta method)."""
    w = np.exp(-1j * wdt)
    nf = theta.size - nb
    powers_b = np.power.outer(w, np.arange(nb))
    powers_f = np.power.outer(w, np.arange(1, nf + 1))
    b = powers_b @ theta[:nb]
    f = 1.0 + powers_f @ theta[nb:]
    grad = np.hstack([powers_b / b[:, None], -powers_f / f[:, None]])  # ∂ log G / ∂θ
    var = np.einsum("ki,ij,kj->k", grad, covariance, np.conj(grad)).real
    return np.sqrt(np.maximum(var, 0.0))
