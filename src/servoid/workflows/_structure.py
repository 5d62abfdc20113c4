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
a position servo has one.  The checks read the model's linear part
(``model.linear`` of a block-oriented model); a model without poles
(NARX) gives none.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..report import Check

__all__ = ["UNSTABLE_MARGIN", "model_poles", "record_dt", "structure_checks", "structure_notes"]

#: |z| − 1 (or Re s·dt) above which a pole counts as unstable: above rounding of the
#: roots of a polynomial with coefficients near 1, far below any pole a record resolves.
UNSTABLE_MARGIN = 1e-6
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


def _issues(model: Any, dt: float | None) -> tuple[list[str], list[str]]:
    """(unstable poles, poles beyond the resolvable band), each as text."""
    found = model_poles(model)
    if found is None:
        return [], []
    poles, model_dt = found
    poles = poles[np.isfinite(poles)]
    unstable: list[str] = []
    fast: list[str] = []
    nyquist = math.pi / dt if dt else math.inf  # rad/s
    for p in poles:
        text = _pole(p)
        if model_dt is not None:  # discrete
            if abs(p) > 1.0 + UNSTABLE_MARGIN:
                unstable.append(f"z = {text} (|z| = {abs(p):.4g})")
            if p.real < 0 and abs(p.imag) <= _REAL * max(abs(p), 1.0) and abs(p) > 1e-6:
                fast.append(f"z = {text} is negative real: no ZOH preimage, it maps to the "
                            f"Nyquist frequency {math.pi / model_dt:.4g} rad/s, so its "
                            "ω_n and ζ are artefacts")
        else:  # continuous
            if p.real * (dt or 1e-3) > UNSTABLE_MARGIN:
                unstable.append(f"s = {text} rad/s")
            if abs(p) > nyquist:
                fast.append(f"s = {text} rad/s: |s| = {abs(p):.4g} rad/s lies beyond the "
                            f"Nyquist frequency π/dt = {nyquist:.4g} rad/s of the record")
    return unstable, fast


def structure_checks(model: Any, dt: float | None) -> list[Check]:
    """Verdict checks on a model's poles: unstable fails, beyond Nyquist cautions.

    Parameters
    ----------
    model
        The identified model (polynomial, transfer function, state space,
        or a block model with a ``linear`` block).
    dt : float or None
        The record's sample time [s] (Nyquist for a continuous model);
        None skips the Nyquist check of a continuous model.
    """
    unstable, fast = _issues(model, dt)
    out = []
    if unstable:
        out.append(Check("stability", f"unstable ({len(unstable)} pole"
                         f"{'s' if len(unstable) > 1 else ''})", "fail",
                         "the returned model is unstable (" + "; ".join(unstable) + "): its "
                         "free run grows without bound; choose another order or method"))
    if fast:
        out.append(Check("poles beyond Nyquist", str(len(fast)), "caution",
                         "; ".join(fast) + " — usually fitted noise or fast dynamics the "
                         "sampling cannot resolve: a lower order, or a faster rate"))
    return out


def structure_notes(model: Any, dt: float | None) -> list[str]:
    """The same findings as notes in words (the console and ``results.json``)."""
    unstable, fast = _issues(model, dt)
    out = []
    if unstable:
        out.append("the returned model is unstable (" + "; ".join(unstable) + "): its free run "
                   "grows without bound on a long record; choose another order or method")
    out += [f"pole {f}" for f in fast]
    return out


def _pole(p: complex) -> str:
    if abs(p.imag) <= _REAL * max(abs(p), 1.0):
        return f"{p.real:.5g}"
    return f"{p.real:.5g} {'+' if p.imag >= 0 else '−'} {abs(p.imag):.4g}j"
