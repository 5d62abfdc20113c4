"""Conversion between continuous and discrete time: ZOH, FOH and Tustin.

ZOH uses the matrix exponential of the augmented matrix ``[[A, B], [0, 0]]``
and its inverse the principal matrix logarithm.  FOH (the triangle hold:
the input is linear between samples) uses the exponential of
``[[A, B, 0], [0, 0, I/dt], [0, 0, 0]]·dt`` and gives the non-causal
equivalent of Franklin, Powell & Workman (*Digital Control of Dynamic
Systems*, 3rd ed., 1998), the same as
:func:`scipy.signal.cont2discrete` with ``method="foh"``; its inverse takes
the logarithm of the state matrix and solves for B and D.  Tustin
(bilinear) maps ``s = k(z − 1)/(z + 1)`` with ``k = 2/dt``, or
``k = ω_p/tan(ω_p·dt/2)`` when prewarped at ω_p [rad/s]; for transfer
functions it is an exact polynomial substitution, for state space the
bilinear formulas.  All inverses are exact, so ``d2c(c2d(G))`` reproduces
G to rounding.

**Delays.**  A continuous transfer function's delay τ = d·dt + f (d whole
samples, 0 <= f < dt) becomes d poles at z = 0, and a fractional part f
one more state that holds the previous input: over a period the plant sees
u(k−1) for the first f seconds and u(k) for the rest (ZOH; the modified
z-transform of Franklin, Powell & Workman), or the two straight pieces
of the delayed ramp (FOH).  Both are exact for their hold.  Tustin has no
such construction and takes whole-sample delays only.  :func:`d2c` (ZOH,
FOH) reads the poles at z = 0 that no zero at z = 0 cancels as a delay of
that many samples, the only preimage they have; a fractional-delay image
then comes back as a biproper model with the next whole-sample delay,
which has the same samples (no record of a held input tells them apart).
Under Tustin a pole at z = 0 is the image of s = −k and is kept as such.

Transfer functions are discretised by ZOH and FOH through a state-space
realisation; their coefficients set the accuracy: a high-order discrete
denominator whose roots cluster near z = 1 (dt much shorter than the time
constants) determines its poles poorly, so keep high-order models in state
space when that matters.
"""

from __future__ import annotations

import math
from typing import overload

import numpy as np

from .._errors import ModelError, OptionTypeError, check_option
from .._lazy import linalg as la
from ._common import METHODS, Method, check_dt, check_method
from ._statespace import StateSpace
from ._transfer import TransferFunction

__all__ = ["c2d", "d2c"]

_EPS = np.finfo(float).eps


@overload
def c2d(
    model: TransferFunction, dt: float, method: Method = ..., prewarp: float | None = ...
) -> TransferFunction: ...
@overload
def c2d(
    model: StateSpace, dt: float, method: Method = ..., prewarp: float | None = ...
) -> StateSpace: ...
def c2d(model, dt, method="zoh", prewarp=None):  # type: ignore[no-untyped-def]
    """Discretise a continuous model.

    Parameters
    ----------
    model : TransferFunction or StateSpace
        Continuous-time model (``dt=None``).
    dt : float
        Sample period [s], > 0.
    method : {"zoh", "tustin", "foh"}
        Zero-order hold, the bilinear (Tustin) map, or first-order
        (triangle) hold.
    prewarp : float, optional
        Tustin only: frequency [rad/s] in (0, π/dt) where the continuous
        and discrete frequency responses agree exactly.

    Returns
    -------
    TransferFunction or StateSpace
        The discrete model, same type; it remembers `method` and `prewarp`.
        A transfer function's delay is in it (see the module notes).

    Raises
    ------
    ModelError
        Tustin of a delay that is not a whole number of samples.

    Examples
    --------
    >>> g = c2d(TransferFunction([1.0], [1.0, 0.0]), 0.1, "tustin")
    >>> [float(x) for x in g.num], [float(x) for x in g.den]
    ([0.05, 0.05], [1.0, -1.0])
    """
    _check_model(model)
    if model.dt is not None:
        raise ModelError(f"c2d needs a continuous-time model (dt=None), got dt = {model.dt} s")
    check_option("method", method, METHODS)
    dt = check_dt(dt, owner="c2d", allow_none=False)
    method, prewarp = check_method(method, prewarp, dt, owner="c2d")
    if isinstance(model, TransferFunction):
        if model.delay:
            return _tf_delayed(model, dt, method, prewarp)
        if method == "tustin":
            return _tf_tustin(model, dt, prewarp)
        return _hold(_balanced(model.to_ss()), dt, method).to_tf()
    if method == "tustin":
        return _ss_tustin(model, dt, prewarp)
    return _hold(model, dt, method)


@overload
def d2c(
    model: TransferFunction, method: Method | None = ..., prewarp: float | None = ...
) -> TransferFunction: ...
@overload
def d2c(
    model: StateSpace, method: Method | None = ..., prewarp: float | None = ...
) -> StateSpace: ...
def d2c(model, method=None, prewarp=None):  # type: ignore[no-untyped-def]
    """Return the continuous model that discretises to ``model``.

    Parameters
    ----------
    model : TransferFunction or StateSpace
        Discrete-time model.
    method : {"zoh", "tustin", "foh"} or None
        Inverse to apply.  None uses the method the model remembers, and
        "zoh" if it remembers none.
    prewarp : float, optional
        Tustin prewarp [rad/s].  None uses the model's own prewarp when the
        method is the one it remembers.

    Returns
    -------
    TransferFunction or StateSpace
        The continuous model (``dt=None``), same type.  ZOH/FOH: poles of
        a transfer function at z = 0 become its delay (module notes).

    Raises
    ------
    ModelError
        ZOH/FOH: a pole on the negative real axis, or at 0 in state space,
        has no real continuous-time preimage.  Tustin: a pole at z = −1
        maps to s = ∞.

    Notes
    -----
    The ZOH inverse is the principal matrix logarithm: a continuous pole
    whose imaginary part exceeded the Nyquist frequency π/dt before
    sampling comes back aliased into (−π/dt, π/dt].
    """
    _check_model(model)
    if model.dt is None:
        raise ModelError("d2c needs a discrete-time model, got a continuous one (dt=None)")
    if method is None:
        method = model.method or "zoh"
    check_option("method", method, METHODS)
    if prewarp is None and method == model.method:
        prewarp = model.prewarp
    method, prewarp = check_method(method, prewarp, model.dt, owner="d2c")
    if isinstance(model, TransferFunction):
        if method == "tustin":
            return _tf_tustin_inverse(model, prewarp)
        return _tf_hold_inverse(model, method)
    if method == "tustin":
        return _ss_tustin_inverse(model, prewarp)
    return _ss_foh_inverse(model) if method == "foh" else _ss_zoh_inverse(model)


def _check_model(model: object) -> None:
    if not isinstance(model, (TransferFunction, StateSpace)):
        raise OptionTypeError(
            f"model must be a TransferFunction or StateSpace, got {type(model).__name__}"
        )


def _tustin_k(dt: float, prewarp: float | None) -> float:
    """Return k in s = k(z − 1)/(z + 1)."""
    if prewarp is None:
        return 2.0 / dt
    return prewarp / math.tan(prewarp * dt / 2.0)


def _substitute(
    coeffs: np.ndarray, n: int, top: tuple[float, float], bottom: tuple[float, float]
) -> np.ndarray:
    """Return Σ c_j·top(x)^m_j·bottom(x)^(n − m_j) for descending ``coeffs``.

    ``top`` and ``bottom`` are first-order polynomials (slope, offset);
    m_j is the power c_j multiplies.  Coefficients smaller than the
    rounding bound of this very sum are set to exact zeros, so structural
    zeros (an integrator, missing high powers) stay exact.
    """
    deg = coeffs.size - 1
    out = np.zeros(n + 1)
    bound = np.zeros(n + 1)
    t_abs = np.abs(top)
    b_abs = np.abs(bottom)
    for j, cj in enumerate(coeffs):
        m = deg - j
        term = np.polymul(_power(top, m), _power(bottom, n - m))
        out[n + 1 - term.size :] += cj * term
        mag = np.polymul(_power(t_abs, m), _power(b_abs, n - m))
        bound[n + 1 - mag.size :] += abs(cj) * mag
    out[np.abs(out) <= 4 * (n + 1) * _EPS * bound] = 0.0
    return out


def _power(p: tuple[float, float] | np.ndarray, m: int) -> np.ndarray:
    out = np.ones(1)
    for _ in range(m):
        out = np.polymul(out, p)
    return out


def _tf_tustin(model: TransferFunction, dt: float, prewarp: float | None) -> TransferFunction:
    k = _tustin_k(dt, prewarp)
    n = model.order
    # s^m -> k^m (z − 1)^m (z + 1)^(n − m), after multiplying through by (z + 1)^n
    num = _substitute(model.num, n, (k, -k), (1.0, 1.0))
    den = _substitute(model.den, n, (k, -k), (1.0, 1.0))
    if den[0] == 0.0:
        raise ModelError("Tustin: the model has a pole at s = k (maps to z = ∞)")
    return TransferFunction(num, den, dt, "tustin", prewarp)


def _tf_tustin_inverse(model: TransferFunction, prewarp: float | None) -> TransferFunction:
    assert model.dt is not None
    k = _tustin_k(model.dt, prewarp)
    n = model.order
    scale = float(np.sum(np.abs(model.den)))
    if abs(np.polyval(model.den, -1.0)) <= 1e3 * (n + 1) * _EPS * scale:
        raise ModelError(
            "Tustin d2c: a pole at z = -1 has no continuous preimage (it maps to s = ∞); "
            "the model resolves dynamics at the Nyquist frequency"
        )
    # z^m -> (k + s)^m (k − s)^(n − m), after multiplying through by (k − s)^n
    num = _substitute(model.num, n, (1.0, k), (-1.0, k))
    den = _substitute(model.den, n, (1.0, k), (-1.0, k))
    return TransferFunction(num, den, None)


def _ss_tustin(model: StateSpace, dt: float, prewarp: float | None) -> StateSpace:
    # scipy's generalised bilinear form (alpha = 1/2), with T = 2/k when prewarped
    k = _tustin_k(dt, prewarp)
    n = model.n_states
    ima = np.eye(n) - model.A / k
    if np.linalg.cond(ima) > 1.0 / _EPS:
        raise ModelError("Tustin: the model has a pole at s = k (maps to z = ∞)")
    ad = la.solve(ima, np.eye(n) + model.A / k)
    bd = la.solve(ima, model.B) * (2.0 / k)
    cd = la.solve(ima.T, model.C.T).T
    dd = model.D + cd @ model.B / k
    return StateSpace(ad, bd, cd, dd, dt, "tustin", prewarp)


def _ss_tustin_inverse(model: StateSpace, prewarp: float | None) -> StateSpace:
    assert model.dt is not None
    k = _tustin_k(model.dt, prewarp)
    n = model.n_states
    ipa = np.eye(n) + model.A
    if n and np.linalg.cond(ipa) > 1e-3 / _EPS:
        raise ModelError(
            "Tustin d2c: a pole at z = -1 has no continuous preimage (it maps to s = ∞)"
        )
    # exact inverse of _ss_tustin: with M = (I + Ad)⁻¹, A = k(Ad − I)M, B = k·M·Bd,
    # C = 2·Cd·M, D = Dd − Cd·M·Bd
    a = k * la.solve(ipa.T, (model.A - np.eye(n)).T).T
    mb = la.solve(ipa, model.B)
    c = 2.0 * la.solve(ipa.T, model.C.T).T
    return StateSpace(a, k * mb, c, model.D - model.C @ mb, None)


def _tf_delayed(
    model: TransferFunction, dt: float, method: str, prewarp: float | None
) -> TransferFunction:
    """Discretise ``G(s)·e^{−sτ}``: whole samples as poles at 0, the rest as a state."""
    steps = model.delay / dt
    whole = round(steps)
    if abs(steps - whole) <= 1e-9 * max(1.0, steps):  # on the grid up to rounding of τ/dt
        d, frac = int(whole), 0.0
    else:
        d = math.floor(steps)
        frac = model.delay - d * dt
    rational = TransferFunction(model.num, model.den)
    if method == "tustin":
        if frac:
            raise ModelError(
                f"Tustin represents only whole-sample delays: delay = {model.delay} s is "
                f"{steps:.6g} samples at dt = {dt} s. Use method='zoh' or 'foh' (exact for a "
                "fractional delay) or a dt that divides the delay"
            )
        g = _tf_tustin(rational, dt, prewarp)
    elif frac:
        g = _ss_fractional(_balanced(rational.to_ss()), dt, frac, method).to_tf()
    else:
        g = _hold(_balanced(rational.to_ss()), dt, method).to_tf()
    return TransferFunction(g.num, np.concatenate([g.den, np.zeros(d)]), dt, g.method, g.prewarp)


def _tf_hold_inverse(model: TransferFunction, method: str) -> TransferFunction:
    """ZOH/FOH inverse of a transfer function; uncancelled poles at z = 0 are its delay."""
    assert model.dt is not None
    den_lag = _trailing_zeros(model.den)
    num_lag = _trailing_zeros(model.num) if np.any(model.num) else 0
    k = den_lag - num_lag
    rational = model
    if k > 0:
        den = model.den[: model.den.size - k]
        if model.num.size > den.size:
            raise ModelError(
                f"{method.upper()} d2c: after its {k} poles at z = 0 the model is improper, "
                "so they are not a whole-sample delay (a fractional delay under FOH, or no "
                f"hold equivalent); convert it with method='tustin' or keep it discrete"
            )
        rational = TransferFunction(model.num, den, model.dt, model.method, model.prewarp)
    ss = _balanced(rational.to_ss())
    back = (_ss_foh_inverse(ss) if method == "foh" else _ss_zoh_inverse(ss)).to_tf()
    if method == "foh":  # FOH keeps a rounding-level feed-through of a strictly proper model
        back = _drop_rounding_lead(back, rational)
    return TransferFunction(back.num, back.den, delay=max(k, 0) * model.dt)


def _trailing_zeros(coeffs: np.ndarray) -> int:
    nz = np.flatnonzero(coeffs)
    return int(coeffs.size - 1 - nz[-1]) if nz.size else 0


def _drop_rounding_lead(back: TransferFunction, image: TransferFunction) -> TransferFunction:
    """Set a leading numerator coefficient at rounding level to an exact zero."""
    if back.num.size < back.den.size or back.num.size < 2 or image.num.size < image.den.size:
        return back
    # D = D_d − C·M2·B cancels to the rounding of logm and solve (~1e-13·|D_d| when seen)
    if abs(back.num[0]) <= 1e-8 * abs(float(image.num[0])):
        return TransferFunction(back.num[1:], back.den)
    return back


def _hold(model: StateSpace, dt: float, method: str) -> StateSpace:
    return _ss_foh(model, dt) if method == "foh" else _ss_zoh(model, dt)


def _ss_foh(model: StateSpace, dt: float) -> StateSpace:
    n, m = model.n_states, model.n_inputs
    e = _ramp_exponential(model.A, model.B, dt)
    phi, p, q = e[:n, :n], e[:n, n : n + m], e[:n, n + m :]
    # x(k+1) = Φx + P·u(k) + Q·(u(k+1) − u(k)); the state ξ = x − Q·u(k) makes it causal
    return StateSpace(phi, p - q + phi @ q, model.C, model.D + model.C @ q, dt, "foh")


def _ss_foh_inverse(model: StateSpace) -> StateSpace:
    assert model.dt is not None
    n = model.n_states
    a = _log_state_matrix(model.A, "FOH") / model.dt
    e = _ramp_exponential(a, np.eye(n), model.dt)
    m1, m2 = e[:n, n : 2 * n], e[:n, 2 * n :]  # P = M1·B, Q = M2·B
    b = la.solve(model.A @ m2 + m1 - m2, model.B)
    return StateSpace(a, b, model.C, model.D - model.C @ m2 @ b, None)


def _ramp_exponential(a: np.ndarray, b: np.ndarray, dt: float) -> np.ndarray:
    """Return expm of [[A, B, 0], [0, 0, I/dt], [0, 0, 0]]·dt (Van Loan)."""
    n, m = b.shape
    big = np.zeros((n + 2 * m, n + 2 * m))
    big[:n, :n] = a * dt
    big[:n, n : n + m] = b * dt
    big[n : n + m, n + m :] = np.eye(m)
    return _scaled(la.expm, big)


def _ss_fractional(model: StateSpace, dt: float, frac: float, method: str) -> StateSpace:
    """Exact discrete model of ``ẋ = Ax + Bu(t − f)``, 0 < f < dt, one extra state per input.

    Over [k·dt, k·dt + f) the plant sees the previous period's input and over
    the rest the current one; the extra state holds u(k − 1).
    """
    n, m = model.n_states, model.n_inputs
    early = _ramp_exponential(model.A, model.B, frac)  # first piece, length f
    late = _ramp_exponential(model.A, model.B, dt - frac)  # second piece, length dt − f
    e_late = late[:n, :n]
    phi = e_late @ early[:n, :n]
    p1, q1 = early[:n, n : n + m], early[:n, n + m :]
    p2, q2 = late[:n, n : n + m], late[:n, n + m :]
    c, d = model.C, model.D
    if method == "zoh":
        c_prev, c_now, c_next = e_late @ p1, p2, np.zeros((n, m))
        d_prev, d_now = d, np.zeros_like(d)
    else:
        # the delayed ramp: from ρ·u(k−1) + (1−ρ)·u(k) to u(k) over the first piece, then
        # towards ρ·u(k) + (1−ρ)·u(k+1) over the second; ρ = f/dt
        rho = frac / dt
        c_prev = rho * e_late @ (p1 - q1)
        c_now = e_late @ ((1.0 - rho) * (p1 - q1) + q1) + p2 - (1.0 - rho) * q2
        c_next = (1.0 - rho) * q2
        d_prev, d_now = rho * d, (1.0 - rho) * d
    # state (x − c_next·u(k), u(k − 1)) makes the non-causal FOH term causal
    a_aug = np.block([[phi, c_prev], [np.zeros((m, n)), np.zeros((m, m))]])
    b_aug = np.vstack([phi @ c_next + c_now, np.eye(m)])
    c_aug = np.hstack([c, d_prev])
    return StateSpace(a_aug, b_aug, c_aug, c @ c_next + d_now, dt, method)  # type: ignore[arg-type]


def _log_state_matrix(phi: np.ndarray, label: str) -> np.ndarray:
    """Return the real principal logarithm of a discrete state matrix."""
    p = la.eigvals(phi)
    bad = p[(np.abs(p.imag) <= 1e-12 * np.maximum(np.abs(p), 1.0)) & (p.real <= 1e-12)]
    if bad.size:
        raise ModelError(
            f"{label} d2c: discrete pole(s) {bad} on the negative real axis or at 0 have no "
            "real continuous-time equivalent (log of a negative number is complex); such "
            "poles usually model dynamics faster than the Nyquist frequency. Try "
            "method='tustin' or reduce the model"
        )
    log = _scaled(la.logm, phi)
    if np.iscomplexobj(log):
        if np.max(np.abs(log.imag)) > 1e-8 * max(1.0, float(np.max(np.abs(log.real)))):
            raise ModelError(f"{label} d2c: the matrix logarithm is not real; no real preimage")
        log = log.real
    return np.asarray(log, dtype=np.float64)


def _ss_zoh(model: StateSpace, dt: float) -> StateSpace:
    n, m = model.n_states, model.n_inputs
    aug = np.zeros((n + m, n + m))
    aug[:n, :n] = model.A
    aug[:n, n:] = model.B
    e = _scaled(la.expm, aug * dt)
    return StateSpace(e[:n, :n], e[:n, n:], model.C, model.D, dt, "zoh")


def _ss_zoh_inverse(model: StateSpace) -> StateSpace:
    assert model.dt is not None
    n, m = model.n_states, model.n_inputs
    p = la.eigvals(model.A)
    bad = p[(np.abs(p.imag) <= 1e-12 * np.maximum(np.abs(p), 1.0)) & (p.real <= 1e-12)]
    if bad.size:
        raise ModelError(
            f"ZOH d2c: discrete pole(s) {bad} on the negative real axis or at 0 have no real "
            "continuous-time equivalent (log of a negative number is complex); such poles "
            "usually model dynamics faster than the Nyquist frequency. Try method='tustin' "
            "or reduce the model"
        )
    aug = np.eye(n + m)
    aug[:n, :n] = model.A
    aug[:n, n:] = model.B
    log = _scaled(la.logm, aug) / model.dt
    if np.iscomplexobj(log):
        if np.max(np.abs(log.imag)) > 1e-8 * max(1.0, float(np.max(np.abs(log.real)))):
            raise ModelError("ZOH d2c: the matrix logarithm is not real; no real preimage")
        log = log.real
    return StateSpace(log[:n, :n], log[:n, n:], model.C, model.D, None)


def _scaled(func, mat: np.ndarray) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Apply expm/logm after diagonal balancing by powers of 2 (exact to undo).

    Companion realisations of high-order models have entries spanning many
    decades; balancing keeps the norm near the spectral radius, which the
    scaling-and-squaring algorithms need for full accuracy.
    """
    if mat.shape[0] == 0:
        return mat.copy()
    _, (scale, _) = la.matrix_balance(mat, permute=False, separate=True)
    balanced = mat / scale[:, None] * scale[None, :]
    return func(balanced) * scale[:, None] / scale[None, :]


def _balanced(model: StateSpace) -> StateSpace:
    """Return a diagonally balanced realisation (powers-of-2 scaling)."""
    if model.n_states == 0:
        return model
    _, (scale, _) = la.matrix_balance(model.A, permute=False, separate=True)
    return StateSpace(
        model.A / scale[:, None] * scale[None, :],
        model.B / scale[:, None],
        model.C * scale[None, :],
        model.D,
        model.dt,
        model.method,
        model.prewarp,
    )
