"""Uncertainty of a frequency response, carried from the parameter covariance.

For an estimate θ̂ with covariance P and a model G(jω, θ), the delta
method gives, to first order, ``Var(Re G, Im G) = J P Jᵀ`` with J the
derivative of (Re G, Im G) in θ; the magnitude [dB] and phase [deg]
variances follow from the same linearisation (Ljung, *System
Identification*, 2nd ed., §9.4).  J is taken by central differences of
the model built at θ̂ ± h·e_i, which only needs the estimator's
``model_function`` — not the estimator's own gradient.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array, as_instance, as_int
from .._errors import DataError
from ._estimate import Estimate

__all__ = ["FrequencyBand", "frequency_band"]


@dataclass(frozen=True, eq=False)
class FrequencyBand:
    """A model's frequency response with its standard deviations.

    Attributes
    ----------
    frequency : ndarray
        Frequencies [Hz].
    response : ndarray of complex
        G at θ̂.
    magnitude_std_db : ndarray
        Standard deviation of 20·log10|G| [dB].
    phase_std_deg : ndarray
        Standard deviation of the phase [deg].
    """

    frequency: NDArray[np.float64]
    response: NDArray[np.complex128]
    magnitude_std_db: NDArray[np.float64]
    phase_std_deg: NDArray[np.float64]

    @property
    def magnitude_db(self) -> NDArray[np.float64]:
        """20·log10|G| [dB]."""
        return np.asarray(20.0 * np.log10(np.abs(self.response)), dtype=float)

    @property
    def phase_deg(self) -> NDArray[np.float64]:
        """Phase unwrapped along frequency [deg]."""
        return np.asarray(np.degrees(np.unwrap(np.angle(self.response))), dtype=float)


def frequency_band(estimate: Estimate, frequency: ArrayLike, *, input: int = 0,
                   output: int = 0) -> FrequencyBand:
    """Return an estimate's frequency response with ±σ bands.

    Parameters
    ----------
    estimate : Estimate
        With a ``model_function`` (every LTI estimator of servoid sets one).
    frequency : array_like
        Frequencies [Hz], > 0.
    input, output : int
        Channel of a multi-input or multi-output model.

    Returns
    -------
    FrequencyBand
        Response and standard deviations of magnitude and phase.
    """
    as_instance("estimate", estimate, Estimate, "an Estimate (from a fit_* function)")
    as_int("input", input, minimum=0)
    as_int("output", output, minimum=0)
    f = as_array("frequency", frequency, finite=False).ravel()
    if f.size == 0 or not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise DataError("frequency must be finite values > 0 Hz")
    omega = 2 * np.pi * f
    g0 = _response(estimate.model, omega, input, output)
    theta = estimate.parameters
    cov = estimate.covariance
    n = theta.size
    jac = np.empty((2 * f.size, n))
    for i in range(n):
        h = 1e-6 * max(abs(theta[i]), 1e-3 * max(float(np.sqrt(max(cov[i, i], 0.0))), 1e-12))
        h = max(h, 1e-9)
        up = _response(estimate.model_at(_shift(theta, i, h)), omega, input, output)
        down = _response(estimate.model_at(_shift(theta, i, -h)), omega, input, output)
        d = (up - down) / (2 * h)
        jac[: f.size, i] = d.real
        jac[f.size :, i] = d.imag
    # Var of (Re, Im) per frequency, then of log-magnitude and phase by the chain rule
    jp = jac @ cov
    var_re = np.einsum("ij,ij->i", jp[: f.size], jac[: f.size])
    var_im = np.einsum("ij,ij->i", jp[f.size :], jac[f.size :])
    cov_ri = np.einsum("ij,ij->i", jp[: f.size], jac[f.size :])
    re, im = g0.real, g0.imag
    mag2 = np.maximum(re**2 + im**2, np.finfo(float).tiny)
    # d ln|G| = (re dre + im dim)/|G|²; d∠G = (re dim − im dre)/|G|²
    var_ln = (re**2 * var_re + im**2 * var_im + 2 * re * im * cov_ri) / mag2**2
    var_ph = (im**2 * var_re + re**2 * var_im - 2 * re * im * cov_ri) / mag2**2
    to_db = 20.0 / np.log(10.0)
    return FrequencyBand(
        frequency=f,
        response=g0,
        magnitude_std_db=to_db * np.sqrt(np.clip(var_ln, 0.0, None)),
        phase_std_deg=np.degrees(np.sqrt(np.clip(var_ph, 0.0, None))),
    )


def _shift(theta: NDArray[np.float64], i: int, h: float) -> NDArray[np.float64]:
    out = np.array(theta, dtype=float)
    out[i] += h
    return out


def _response(model: object, omega: NDArray[np.float64], input: int,
              output: int) -> NDArray[np.complex128]:
    if hasattr(model, "transfer_function"):  # PolynomialModel
        model = model.transfer_function(input)
    g = np.asarray(model.freqresp(omega))  # type: ignore[attr-defined]
    if g.ndim == 3:  # state space with several channels: (n_omega, p, m)
        g = g[:, output, input]
    return np.asarray(g, dtype=np.complex128).ravel()
