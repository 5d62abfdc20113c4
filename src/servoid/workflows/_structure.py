"""Checks on the identified structure itself, for every method's verdict.

What the poles of a returned model say before any record is simulated:

* an **unstable** model (a discrete pole outside the unit circle, a
  continuous one in the right half-plane) fails: its free run grows
  without bound on a long enough record, whatever its fit on a short one;
* a **negative real** discrete pole has no zero-order-hold preimage (it
  maps to the Nyquist frequency π/dt), and a continuous pole or a pair
  with ω_n beyond Nyquist describes dynamics the sampling cannot resolve:
  both are usually fitted noise or unresolvable fast dynamics, and are a
  caution with the poles named.

An integrator (a pole on the unit circle at z = 1, at s = 0) is neither:
a position servo has one.  A pole just outside the boundary is judged by
its confidence region (:func:`pole_spread`, the delta method on the
estimate's covariance): within :data:`MARGINAL_SIGMAS` standard deviations
and within 0.05 of z = 1 it is a caution (an integrator the data cannot
tell from a slightly unstable pole), otherwise a failure.  The checks read the model's linear part
(``model.linear`` of a block-oriented model); a model without poles
(NARX) gives none.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..report import Check

__all__ = ["MARGINAL_SIGMAS", "UNSTABLE_MARGIN", "model_poles", "pole_spread", "record_dt", "structure_checks", "structure_notes"]

#: |z| − 1 (or Re s·dt) above which a pole counts as unstable: above rounding of the
#: roots of a polynomial with coefficients near 1, far below any pole a record resolves.
UNSTABLE_MARGIN = 1e-6
#: Standard deviations of a pole's |z| (Re s) within which a pole just outside the
#: stability boundary is an integrator the data cannot resolve, not an unstable model.
MARGINAL_SIGMAS = 2.0
#: Farthest a marginal pole lies from z = 1 (a time constant of 20 samples): a pole
#: farther out is no integrator, however uncertain.
_NEAR_ONE = 0.05
#: Imaginary part (relative) below which a negative pole counts as real.
_REAL = 1e-9


def model_poles(model: Any) -> tuple[np.ndarray, float | None] | None:
    """The poles of a model's linear part and its sample time (None: continuous).

    None when the model has no poles to read (a NARX, a grey-box ODE).
    """
    lin = getattr(model, "linear", None)
    if lin is not None and hasattr(lin, "poles"):
        model = lin
    try:
        if hasattr(model, "transfer_function"):  # PolynomialModel
            tf = model.transfer_function(0)
            return np.asarray(tf.poles(), dtype=complex), tf.dt
        if hasattr(model, "poles"):
            return np.asarray(model.poles(), dtype=complex), getattr(model, "dt", None)
    except (ValueError, np.linalg.LinAlgError, TypeError):
        return None
    return None


def record_dt(validations: Any, model: Any) -> float | None:
    """The sample time of the first validation that ran, else the model's."""
    for v in validations:
        time = getattr(v, "time", None)
        if isinstance(time, np.ndarray) and time.size > 1:
            return float(time[1] - time[0])
    dt = getattr(getattr(model, "linear", model), "dt", None) or getattr(model, "dt", None)
    return float(dt) if dt else None


def pole_spread(estimate: Any, pole: complex) -> float:
    """Standard deviation of |z| of one discrete pole (of s·dt-free Re s, continuous).

    By the delta method through ``estimate.model_at``: each parameter moved
    by ±max(10⁻³·σ_i, 10⁻⁸·|θ_i|) and the perturbed pole matched to the
    nominal one by distance.  NaN without a covariance or a model function.
    """
    try:
        cov = np.asarray(estimate.covariance, dtype=float)
        theta = np.asarray(estimate.parameters, dtype=float)
        std = np.sqrt(np.diag(cov))
    except (AttributeError, TypeError, ValueError):
        return math.nan
    if estimate.model_function is None or not np.all(np.isfinite(cov)) or theta.size == 0:
        return math.nan
    discrete = model_poles(estimate.model)
    if discrete is None:
        return math.nan
    measure = abs if discrete[1] is not None else (lambda z: z.real)
    grad = np.zeros(theta.size)
    for k in range(theta.size):
        h = max(1e-3 * std[k], 1e-8 * abs(theta[k]), 1e-12)
        values = []
        for sign in (1.0, -1.0):
            t = theta.copy()
            t[k] += sign * h
            try:
                moved = model_poles(estimate.model_at(t))
            except Exception:  # noqa: BLE001 - a model_at that fails gives no spread
                return math.nan
            if moved is None or moved[0].size == 0:
                return math.nan
            values.append(measure(moved[0][np.argmin(np.abs(moved[0] - pole))]))
        grad[k] = (values[0] - values[1]) / (2 * h)
    var = float(grad @ cov @ grad)
    return math.sqrt(var) if var >= 0 else math.nan


def _issues(model: Any, dt: float | None, estimate: Any = None
            ) -> tuple[list[str], list[str], list[str]]:
    """(unstable poles, marginal poles, poles beyond the resolvable band), each as text.

    A pole outside the stability boundary by less than :data:`MARGINAL_SIGMAS` of its
    own standard deviation (``estimate`` given) is *marginal*: an integrator within the
    data's resolution, not an unstable model.
    """
    found = model_poles(model)
    if found is None:
        return [], [], []
    poles, model_dt = found
    poles = poles[np.isfinite(poles)]
    unstable: list[str] = []
    marginal: list[str] = []
    fast: list[str] = []
    nyquist = math.pi / dt if dt else math.inf  # rad/s
    for p in poles:
        text = _pole(p)
        if model_dt is not None:  # discrete
            if abs(p) > 1.0 + UNSTABLE_MARGIN:
                sigma = pole_spread(estimate, p) if estimate is not None else math.nan
                if abs(p - 1.0) < min(MARGINAL_SIGMAS * sigma, _NEAR_ONE):
                    marginal.append(f"z = {text} (|z| − 1 = {abs(p) - 1:.2g}, σ of |z| "
                                    f"{sigma:.2g})")
                else:
                    unstable.append(f"z = {text} (|z| = {abs(p):.6g})")
            if p.real < 0 and abs(p.imag) <= _REAL * max(abs(p), 1.0) and abs(p) > 1e-6:
                fast.append(f"z = {text} is negative real: no ZOH preimage, it maps to the "
                            f"Nyquist frequency {math.pi / model_dt:.4g} rad/s, so its "
                            "ω_n and ζ are artefacts")
        else:  # continuous
            if p.real * (dt or 1e-3) > UNSTABLE_MARGIN:
                sigma = pole_spread(estimate, p) if estimate is not None else math.nan
                if abs(p) < min(MARGINAL_SIGMAS * sigma, _NEAR_ONE / (dt or 1e-3)):
                    marginal.append(f"s = {text} rad/s (σ of Re s {sigma:.2g})")
                else:
                    unstable.append(f"s = {text} rad/s")
            if abs(p) > nyquist:
                fast.append(f"s = {text} rad/s: |s| = {abs(p):.4g} rad/s lies beyond the "
                            f"Nyquist frequency π/dt = {nyquist:.4g} rad/s of the record")
    return unstable, marginal, fast


def structure_checks(model: Any, dt: float | None, estimate: Any = None, *,
                     in_loop: bool = False) -> list[Check]:
    """Verdict checks on a model's poles: unstable fails, beyond Nyquist cautions.

    Parameters
    ----------
    model
        The identified model (polynomial, transfer function, state space,
        or a block model with a ``linear`` block).
    dt : float or None
        The record's sample time [s] (Nyquist for a continuous model);
        None skips the Nyquist check of a continuous model.
    estimate
        The estimate behind the model (its covariance places a pole near 1).
    in_loop : bool
        The plant came from a closed-loop record and was validated inside its
        loop: an unstable plant is then what was identified, not a failure.
    """
    unstable, marginal, fast = _issues(model, dt, estimate)
    out = []
    if marginal:
        out.append(Check("stability", "an integrator within its uncertainty", "caution",
                         "a pole lies just outside the stability boundary, within "
                         f"{MARGINAL_SIGMAS:g}σ of it (" + "; ".join(marginal) + "): the data "
                         "cannot tell an integrator from a slightly unstable pole; its free run "
                         "drifts on a long record"))
    if unstable and in_loop:
        out.append(Check("stability", f"unstable plant ({len(unstable)} pole"
                         f"{'s' if len(unstable) > 1 else ''})", "info",
                         "the identified plant is unstable (" + "; ".join(unstable) + "), as a "
                         "plant its loop stabilises may be: it was validated inside that loop; "
                         "it runs free only with its controller"))
    elif unstable:
        out.append(Check("stability", f"unstable ({len(unstable)} pole"
                         f"{'s' if len(unstable) > 1 else ''})", "fail",
                         "the returned model is unstable (" + "; ".join(unstable) + "): its "
                         "free run grows without bound; choose another order or method"))
    if fast:
        out.append(Check("poles beyond Nyquist", str(len(fast)), "caution",
                         "; ".join(fast) + " — usually fitted noise or fast dynamics the "
                         "sampling cannot resolve: a lower order, or a faster rate"))
    return out


def structure_notes(model: Any, dt: float | None, estimate: Any = None, *,
                    in_loop: bool = False) -> list[str]:
    """The same findings as notes in words (the console and ``results.json``)."""
    unstable, marginal, fast = _issues(model, dt, estimate)
    out = [f"a pole at the stability boundary within its uncertainty ({m}): an integrator "
           "or a slightly unstable pole" for m in marginal]
    if unstable and not in_loop:  # validated in its loop: the loop's note says it
        out.append("the returned model is unstable (" + "; ".join(unstable) + "): its free run "
                   "grows without bound on a long record; choose another order or method")
    out += [f"pole {f}" for f in fast]
    return out


def _pole(p: complex) -> str:
    if abs(p.imag) <= _REAL * max(abs(p), 1.0):
        return f"{p.real:.5g}"
    return f"{p.real:.5g} {'+' if p.imag >= 0 else '−'} {abs(p.imag):.4g}j"
