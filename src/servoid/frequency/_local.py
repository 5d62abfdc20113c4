"""The local polynomial and local rational methods: FRF and noise from any record.

The DFT of a record of N samples of a linear system is, exactly,

    Y(k) = G(Ω_k)·U(k) + T(Ω_k) + V(k),

with T the transient (the difference of the initial and final
conditions, which is what leakage is) and V the noise (Pintelon &
Schoukens, *System Identification: A Frequency Domain Approach*, 2nd
ed., 2012).  G and T are smooth in k, the noise is not.  The local
polynomial method (LPM; Pintelon, Schoukens, Vandersteen & Barbé, *Mech.
Syst. Signal Process.* 24, 2010) fits, around each line k, over the 2n + 1
lines k + r (|r| <= n),

    Y(k + r) = Σ_{j<=R} g_j·r^j · U(k + r) + Σ_{j<=R} t_j·r^j + V(k + r)

by least squares; Ĝ(k) = g_0, and the transient is gone with the t_j.
The residuals leave ``q = 2n + 1 − 2(R + 1)`` complex degrees of freedom,
so the noise variance is ``σ̂²_V(k) = Σ|residual|²/q`` and

    var Ĝ(k) = σ̂²_V(k)·[(KᴴK)⁻¹]_00,

with K the regressor of the window (Pintelon et al. 2010, Part I).  The
estimate and the residual are independent for Gaussian noise, so
``|Ĝ − G|²/var Ĝ`` follows F(2, 2q).  Estimates whose windows do not
overlap (2n + 1 lines apart) are independent.

Since the transient columns are the same at every line (powers of r),
they are projected out once (the Frisch–Waugh–Lovell theorem): every
window is multiplied by an orthonormal basis of the complement of those
columns, which leaves ``2n + 1 − (R + 1)`` equations for the R + 1
coefficients of G, solved for all lines at once through a Cholesky
factor of their normal equations.  At the band edges the window is
shifted inwards and the polynomial evaluated off-centre.

The local rational method (LRM; McKelvey & Guérin, IFAC SYSID 2012)
models the window as ``(B(r)/A(r))·U + T(r)/A(r)`` with ``A(0) = 1``,
linearised as ``Y·A(r) = B(r)·U + T(r)``; a lightly damped resonance
inside one window is then rational, not polynomial, and its bias is
smaller.  The noise on Y in the regressor biases that linearised fit at
low signal-to-noise ratio and the variance is then approximate.

In closed loop (``reference=``) the noise enters the input, so the
plant is not Y/U: the LPM fits Y and U on the reference, ``[Y; U] =
[G_yr; G_ur]·R + T + V``, with the 2 × 2 noise covariance C_V from the
joint residuals, and ``Ĝ = Ĝ_yr/Ĝ_ur`` with, to first order,

    var Ĝ = h·(C_yy + |Ĝ|²·C_uu − 2·Re(conj(Ĝ)·C_yu))/|Ĝ_ur|²,

``h = [(KᴴK)⁻¹]_00`` (Pintelon et al. 2010, Part II).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from .._checks import as_float, as_int
from .._errors import DataError, OptionTypeError
from ..data import Experiment
from ..estimate import frf_channels as _io_channels
from ._measured import FrfMeasurement

__all__ = ["estimate_lpm", "estimate_lrm"]

# lines solved per block: the regressors of a block stay in cache (about 1.5 MB)
_BLOCK = 8192
# a line's window counts as excited when its input power is above this fraction of the most
_UNEXCITED = 1e-20


def estimate_lpm(
    data: Experiment,
    *,
    input: str = "u",
    output: str | None = None,
    reference: str | None = None,
    degree: int = 2,
    half_width: int | None = None,
    f_min: float | None = None,
    f_max: float | None = None,
) -> FrfMeasurement:
    """FRF and noise variance by the local polynomial method.

    Parameters
    ----------
    data : Experiment
        The record: any input (noise, a swept sine, a multisine with every
        line excited), transients included.
    input : str
        Input channel (a name, or a role naming one channel).
    output : str, optional
        Output channel; default the only ``y`` channel.
    reference : str, optional
        Reference channel of a closed-loop record: G from ``Y/R`` over
        ``U/R`` (module notes).
    degree : int
        Degree R of the local polynomials (>= 0).
    half_width : int, optional
        n: the window is 2n + 1 lines.  Default the smallest n leaving
        ``q = 2(R + 1) + 1`` degrees of freedom (n = 6 for R = 2).
    f_min, f_max : float, optional
        Band of lines to return [Hz]; default DC (excluded) to Nyquist.

    Returns
    -------
    FrfMeasurement
        Every line in the band, with ``variance = noise_variance``,
        ``dof = q`` and ``stride = 2n + 1``.

    Raises
    ------
    DataError
        Fewer lines than a window, a constant input, a band without lines.

    Examples
    --------
    >>> import numpy as np
    >>> from servoid.data import Experiment
    >>> from servoid.frequency import estimate_lpm
    >>> u = np.random.default_rng(0).standard_normal(4096)
    >>> y = 0.5 * u + 0.25 * np.concatenate([[0.0], u[:-1]])  # starts at rest
    >>> frm = estimate_lpm(Experiment.from_arrays(0.01, u=u, y=y))
    >>> g = 0.5 + 0.25 * np.exp(-1j * frm.omega * 0.01)
    >>> frm.dof, bool(np.allclose(frm.response, g, atol=1e-6))
    (7.0, True)
    """
    return _estimate(data, input, output, reference, degree, 0, half_width, f_min, f_max,
                     "lpm")


def estimate_lrm(
    data: Experiment,
    *,
    input: str = "u",
    output: str | None = None,
    degree: int = 2,
    denominator: int = 2,
    half_width: int | None = None,
    f_min: float | None = None,
    f_max: float | None = None,
) -> FrfMeasurement:
    """Frequency response by the local rational method (open loop).

    Parameters
    ----------
    data : Experiment
        The record (any input, transients included).
    input, output : str
        Channels, as for :func:`estimate_lpm`.
    degree : int
        Degree of the local numerator and transient polynomials (>= 0).
    denominator : int
        Degree of the local denominator A(r), A(0) = 1 (>= 1).
    half_width : int, optional
        n; default leaves ``q = 2(R + 1) + 1`` degrees of freedom.
    f_min, f_max : float, optional
        Band of lines to return [Hz].

    Returns
    -------
    FrfMeasurement
        As :func:`estimate_lpm`; the variance neglects the noise on the
        output in the linearised regressor (module notes).
    """
    den = as_int("denominator", denominator, minimum=1, maximum=10)
    return _estimate(data, input, output, None, degree, den, half_width, f_min, f_max, "lrm")


def _estimate(data: Experiment, input: str, output: str | None, reference: str | None,
              degree: int, den: int, half_width: int | None, f_min: float | None,
              f_max: float | None, method: str) -> FrfMeasurement:
    if not isinstance(data, Experiment):
        raise OptionTypeError(f"data must be an Experiment, got {type(data).__name__}")
    r_deg = as_int("degree", degree, minimum=0, maximum=10)
    u_ch, y_ch, r_ch = _io_channels(data, input, output, reference)
    n_poly = r_deg + 1
    n_coef = n_poly + den
    q_default = 2 * n_poly + 1
    if half_width is None:
        n = math.ceil((q_default + n_coef + n_poly - 1) / 2)
    else:
        n = as_int("half_width", half_width, minimum=1)
    width = 2 * n + 1
    q = width - n_coef - n_poly
    if q < 1:
        raise DataError(
            f"half_width = {n} gives windows of {width} lines for {n_coef + n_poly} local "
            f"coefficients: no degree of freedom is left for the noise; use half_width >= "
            f"{math.ceil((n_coef + n_poly) / 2)}"
        )
    dt = data.dt
    n_samples = data.n_samples
    top = (n_samples - 1) // 2  # highest line below Nyquist
    if top < width:
        raise DataError(f"the record of {n_samples} samples has {top} lines between DC and "
                        f"Nyquist, fewer than one window of {width}; record longer or lower "
                        "half_width")
    f0 = 1.0 / (n_samples * dt)
    lo = 1 if f_min is None else max(1, math.ceil(as_float("f_min", f_min, nonneg=True,
                                                            unit="Hz") / f0 - 1e-9))
    hi = top if f_max is None else min(top, math.floor(as_float("f_max", f_max, positive=True,
                                                                unit="Hz") / f0 + 1e-9))
    if hi < lo:
        raise DataError(f"no line of the {f0:g} Hz grid lies in the band [{f_min}, {f_max}] Hz")
    lines = np.arange(lo, hi + 1)
    scale = 1.0 / math.sqrt(n_samples)
    x_ch = u_ch if r_ch is None else r_ch
    x = np.fft.rfft(x_ch.values) * scale
    outs = [np.fft.rfft(y_ch.values) * scale]
    if r_ch is not None:
        outs.append(np.fft.rfft(u_ch.values) * scale)
    z = np.stack(outs)
    if den:
        theta0, h, cov = _local_fit(x, z, lines, n, r_deg, den, top)
    else:
        theta0, h, cov = _polynomial_fit(x, z, lines, n, r_deg, top)
    if r_ch is None:
        g = theta0[0]
        var = h * cov[:, 0, 0].real
    else:
        g_yr, g_ur = theta0[0], theta0[1]
        with np.errstate(divide="ignore", invalid="ignore"):
            g = g_yr / g_ur
            var = h * (cov[:, 0, 0].real + np.abs(g) ** 2 * cov[:, 1, 1].real
                       - 2.0 * np.real(np.conj(g) * cov[:, 0, 1])) / np.abs(g_ur) ** 2
    keep = np.isfinite(g) & np.isfinite(var) & (h > 0)
    if not np.any(keep):
        raise DataError("the input has no power on any line of the band; check the channel "
                        "mapping")
    var = np.maximum(var[keep], 0.0)
    return FrfMeasurement(
        frequency=lines[keep] * f0, response=g[keep], variance=var, noise_variance=var,
        nonlinear_variance=None, dof=float(q), noise_dof=float(q), stride=width, method=method,
        dt=dt, input_name=u_ch.name, output_name=y_ch.name,
        reference_name=None if r_ch is None else r_ch.name, input_unit=u_ch.unit,
        output_unit=y_ch.unit)


def _polynomial_fit(x: NDArray[np.complex128], z: NDArray[np.complex128],
                    lines: NDArray[np.int_], n: int, degree: int, top: int,
                    ) -> tuple[NDArray[np.complex128], NDArray[np.float64],
                               NDArray[np.complex128]]:
    """The LPM by the compiled kernel (same results as :func:`_local_fit` with no denominator)."""
    from ._lpm_kernel import lpm_lines

    width = 2 * n + 1
    n_poly = degree + 1
    r = np.arange(-n, n + 1) / n
    trans = r[:, None] ** np.arange(n_poly)[None, :]
    c_inv = np.linalg.inv(trans.T @ trans)
    starts = np.clip(lines - n, 1, top - width + 1).astype(np.int64)
    n_out = z.shape[0]
    theta0 = np.empty((n_out, lines.size), dtype=np.complex128)
    h = np.empty(lines.size)
    cov = np.empty((lines.size, n_out, n_out), dtype=np.complex128)
    ok = np.empty(lines.size, dtype=np.bool_)
    lpm_lines(np.ascontiguousarray(x), np.ascontiguousarray(z), lines.astype(np.int64), starts,
              n, degree, c_inv, theta0, h, cov, ok)
    # a window without input power (a band-limited input) has no G to speak of
    energy = x.real**2 + x.imag**2
    local = np.convolve(energy, np.ones(width), mode="same")[lines]
    excited = ok & np.isfinite(h) & (local > _UNEXCITED * width * max(float(energy.max()),
                                                                        np.finfo(float).tiny))
    return theta0, np.where(excited, h, np.nan), cov


def _local_fit(x: NDArray[np.complex128], z: NDArray[np.complex128], lines: NDArray[np.int_],
               n: int, degree: int, den: int, top: int,
               ) -> tuple[NDArray[np.complex128], NDArray[np.float64], NDArray[np.complex128]]:
    """Local fits around each line.

    Returns the value of G at each line per output (``(n_out, L)``), the
    factor ``h = c·(KᴴK)⁻¹·c̄`` of its variance, and the residual
    covariance of the outputs per line (``(L, n_out, n_out)``).
    """
    width = 2 * n + 1
    r = np.arange(-n, n + 1) / n  # scaled to [-1, 1]: well-conditioned powers
    n_poly = degree + 1
    trans = r[:, None] ** np.arange(n_poly)[None, :]  # (W, R+1): the transient's columns
    # orthonormal complement of the transient's columns
    qfull, _ = np.linalg.qr(trans, mode="complete")
    perp = qfull[:, n_poly:]  # (W, m)
    m = perp.shape[1]
    gcols = trans  # G's polynomial has the same powers
    acols = r[:, None] ** np.arange(1, den + 1)[None, :] if den else np.zeros((width, 0))
    # Ã[k, i, j] = Σ_w X(k, w)·perp[w, i]·gcols[w, j]: one product with a (W, m·R+1) matrix
    kron_g = (perp[:, :, None] * gcols[:, None, :]).reshape(width, m * n_poly)
    kron_a = (perp[:, :, None] * acols[:, None, :]).reshape(width, m * den)
    n_out = z.shape[0]
    n_coef = n_poly + den
    q = m - n_coef
    count = lines.size
    theta0 = np.empty((n_out, count), dtype=np.complex128)
    h = np.empty(count)
    cov = np.empty((count, n_out, n_out), dtype=np.complex128)
    first = 1
    last_start = top - width + 1
    offsets = np.arange(width)
    for b0 in range(0, count, _BLOCK):
        k = lines[b0:b0 + _BLOCK]
        start = np.clip(k - n, first, last_start)
        r0 = (k - (start + n)) / n  # where G is read inside the window, scaled
        idx = start[:, None] + offsets[None, :]
        xw = x[idx]  # (B, W)
        zw = z[:, idx]  # (n_out, B, W)
        a_t = (xw @ kron_g).reshape(-1, m, n_poly)
        if den:
            a_t = np.concatenate([a_t, -(zw[0] @ kron_a).reshape(-1, m, den)], axis=2)
        z_t = zw @ perp  # (n_out, B, m)
        gram = np.einsum("bic,bid->bcd", a_t.conj(), a_t)
        rhs = np.einsum("bic,obi->bco", a_t.conj(), z_t)
        power = np.einsum("bw,bw->b", xw.real, xw.real) + np.einsum("bw,bw->b", xw.imag,
                                                                     xw.imag)
        chol, ok = _cholesky(gram)
        theta = _chol_solve(chol, rhs)  # (B, nc, n_out)
        resid = z_t - np.einsum("bic,bco->obi", a_t, theta)
        cov[b0:b0 + k.size] = np.einsum("obi,pbi->bop", resid, resid.conj()) / q
        vb = r0[:, None] ** np.arange(n_poly)[None, :]  # (B, R+1)
        b_at = np.einsum("bc,bco->bo", vb, theta[:, :n_poly, :])
        if den:
            va = r0[:, None] ** np.arange(1, den + 1)[None, :]
            a_at = 1.0 + np.einsum("bc,bc->b", va, theta[:, n_poly:, 0])
            g_at = b_at[:, 0] / a_at
            grad = np.concatenate([vb / a_at[:, None], -(g_at / a_at)[:, None] * va], axis=1)
            theta0[0, b0:b0 + k.size] = g_at
        else:
            grad = np.concatenate([vb, np.zeros((k.size, 0))], axis=1)
            theta0[:, b0:b0 + k.size] = b_at.T
        sol = _forward(chol, np.conj(grad)[:, :, None])[:, :, 0]
        hb = np.einsum("bc,bc->b", sol.real, sol.real) + np.einsum("bc,bc->b", sol.imag,
                                                                   sol.imag)
        excited = ok & (power > _UNEXCITED * max(float(power.max()), np.finfo(float).tiny))
        h[b0:b0 + k.size] = np.where(excited, hb, np.nan)
    return theta0, h, cov


def _cholesky(a: NDArray[np.complex128]) -> tuple[NDArray[np.complex128], NDArray[np.bool_]]:
    """Lower Cholesky factors of a batch of small Hermitian matrices (loops over the size)."""
    size = a.shape[-1]
    low = np.zeros_like(a)
    ok = np.ones(a.shape[0], dtype=bool)
    for j in range(size):
        d = a[:, j, j].real - np.einsum("bk,bk->b", low[:, j, :j].real, low[:, j, :j].real) \
            - np.einsum("bk,bk->b", low[:, j, :j].imag, low[:, j, :j].imag)
        scale = np.abs(a[:, j, j].real)
        good = d > 1e-13 * np.maximum(scale, np.finfo(float).tiny)
        ok &= good
        piv = np.sqrt(np.where(good, d, 1.0))
        low[:, j, j] = piv
        if j + 1 < size:
            low[:, j + 1:, j] = (a[:, j + 1:, j] - np.einsum(
                "bik,bk->bi", low[:, j + 1:, :j], low[:, j, :j].conj())) / piv[:, None]
    return low, ok


def _forward(low: NDArray[np.complex128], b: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """Solve L·x = b for a batch (b: (B, n, k))."""
    size = low.shape[-1]
    out = np.empty(b.shape, dtype=np.complex128)
    for i in range(size):
        acc = b[:, i, :] - np.einsum("bk,bkj->bj", low[:, i, :i], out[:, :i, :])
        out[:, i, :] = acc / low[:, i, i][:, None]
    return out


def _chol_solve(low: NDArray[np.complex128], b: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """Solve (L·Lᴴ)·x = b for a batch."""
    w = _forward(low, b)
    size = low.shape[-1]
    out = np.empty_like(w)
    for i in range(size - 1, -1, -1):
        acc = w[:, i, :] - np.einsum("bk,bkj->bj", low[:, i + 1:, i].conj(), out[:, i + 1:, :])
        out[:, i, :] = acc / low[:, i, i][:, None].conj()
    return out

