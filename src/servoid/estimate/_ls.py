"""Linear least squares with parameter covariance.

Two routes give the same answer on well-conditioned problems:

* ``"qr"`` — Householder QR of the column-scaled regressor matrix Φ, the
  reference: its error grows with cond(Φ), not cond(Φ)².
* ``"gram"`` — Cholesky of the column-scaled Gram matrix ΦᵀΦ, for callers that
  can build ΦᵀΦ without forming Φ (ARX does it in one pass over the data).
  Its error grows with cond(Φ)², so :func:`solve_gram` refuses (returns
  None) when the scaled condition number exceeds ``GRAM_COND_LIMIT`` and the
  caller falls back to QR.

Both scale the columns to unit norm first (equilibration): it leaves the
solution unchanged and makes the rank test independent of signal units.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numba
import numpy as np
from numpy.typing import NDArray

from .._checks import as_array, as_int, as_str_list
from .._errors import DataError, IdentifiabilityError
from .._lazy import linalg
from ._channels import check_magnitude

__all__ = ["GRAM_COND_LIMIT", "LeastSquaresResult", "lstsq", "solve_gram"]

LsMethod = Literal["auto", "qr", "gram"]

#: Largest cond(scaled Φ) for which the Gram route is trusted: its relative
#: error is about ε·cond², 2.2e-16·(1e3)² ≈ 2e-10, well inside 1e-8 of QR.
GRAM_COND_LIMIT = 1e3
#: cond(scaled Φ) above which the regressor counts as rank deficient
#: (1/√ε: beyond it the Gram matrix is numerically singular in double precision).
RANK_COND_LIMIT = 1.0 / np.sqrt(np.finfo(float).eps)


@dataclass(frozen=True, eq=False)
class LeastSquaresResult:
    """Solution of min ‖y − Φθ‖² with its covariance.

    Attributes
    ----------
    theta : ndarray, shape (n,)
        Estimated parameters.
    covariance : ndarray, shape (n, n)
        σ̂²(ΦᵀΦ)⁻¹ with σ̂² = RSS / (N − n).
    rss : float
        Residual sum of squares.
    n_rows : int
        Number of equations N.
    condition : float
        Condition number of the column-scaled Φ.
    method : str
        Route actually used, ``"qr"`` or ``"gram"``.
    """

    theta: NDArray[np.float64]
    covariance: NDArray[np.float64]
    rss: float
    n_rows: int
    condition: float
    method: str

    @property
    def dof(self) -> int:
        """Degrees of freedom N − n."""
        return self.n_rows - self.theta.size

    @property
    def noise_variance(self) -> float:
        """Unbiased residual variance σ̂² = RSS/(N − n)."""
        return self.rss / self.dof

    @property
    def std(self) -> NDArray[np.float64]:
        """Standard deviations of the parameters."""
        return np.sqrt(np.diag(self.covariance))


def lstsq(
    phi: NDArray[np.float64], y: NDArray[np.float64], names: tuple[str, ...] | None = None
) -> LeastSquaresResult:
    """Solve min ‖y − Φθ‖² by QR, with covariance.

    Parameters
    ----------
    phi : ndarray, shape (N, n)
        Regressor matrix.
    y : ndarray, shape (N,)
        Left-hand side.
    names : tuple of str, optional
        Column names, used in the rank-deficiency message.

    Raises
    ------
    IdentifiabilityError
        When Φ is rank deficient (a column is zero or a combination of others).
    """
    phi = as_array("phi", phi)
    y = as_array("y", y)
    if phi.ndim != 2 or y.ndim != 1 or phi.shape[0] != y.shape[0]:
        raise DataError(f"need phi (N, n) and y (N,), got {phi.shape} and {y.shape}")
    n_rows, n = phi.shape
    if n == 0:
        raise DataError("phi has no columns: least squares needs at least one parameter")
    names = _names(names, n)
    _check_rows(n_rows, n)
    _check_magnitude(phi, y)
    scale = np.sqrt(np.einsum("ij,ij->j", phi, phi))
    _check_columns(scale, names)
    # Factor [Φ/scale | y] once, keeping only R: Q is never formed, and the last
    # diagonal element of R is ±‖residual‖, so RSS needs no second pass over Φ.
    aug = np.empty((n_rows, n + 1), order="F")
    np.divide(phi, scale, out=aug[:, :n])
    aug[:, n] = y
    r_full = linalg.qr(aug, mode="r", overwrite_a=True, check_finite=False)[0]
    r = np.triu(r_full[:n, :n])
    condition = _triangular_condition(r)
    rdiag = np.abs(np.diag(r))
    if condition > RANK_COND_LIMIT or rdiag.min() <= RANK_COND_LIMIT**-1 * rdiag.max():
        raise _rank_error(condition, names)
    theta_s = linalg.solve_triangular(r, r_full[:n, n])
    rss = float(r_full[n, n] ** 2) if n_rows > n else 0.0
    rinv = linalg.solve_triangular(r, np.eye(n))
    cov_s = rinv @ rinv.T
    sigma2 = rss / max(n_rows - n, 1)
    cov = sigma2 * cov_s / np.outer(scale, scale)
    return LeastSquaresResult(theta_s / scale, cov, rss, n_rows, condition, "qr")


def solve_gram(
    gram: NDArray[np.float64], n_rows: int, names: tuple[str, ...] | None = None
) -> LeastSquaresResult | None:
    """Solve least squares from the augmented Gram matrix [Φ y]ᵀ[Φ y].

    Parameters
    ----------
    gram : ndarray, shape (n + 1, n + 1)
        Gram matrix of the regressors with the left-hand side as last column.
    n_rows : int
        Number of equations N that built it.
    names : tuple of str, optional
        Column names, used in the rank-deficiency message.

    Returns
    -------
    LeastSquaresResult or None
        None when the scaled condition number exceeds ``GRAM_COND_LIMIT``:
        the caller must use QR instead.
    """
    gram = as_array("gram", gram, finite=False)
    if gram.ndim != 2 or gram.shape[0] != gram.shape[1] or gram.shape[0] < 2:
        raise DataError(f"gram must be a square (n + 1, n + 1) matrix with n >= 1, got shape "
                        f"{gram.shape}")
    n_rows = as_int("n_rows", n_rows, minimum=1)
    n = gram.shape[0] - 1
    names = _names(names, n)
    _check_rows(n_rows, n)
    return _solve_gram(gram, n_rows, names)


try:  # the LAPACK gufuncs behind np.linalg.eigvalsh / inv, without their ~10 µs of wrapping
    from numpy.linalg import _umath_linalg

    _eigvalsh_lo = _umath_linalg.eigvalsh_lo
    _inv_gufunc = _umath_linalg.inv
except (ImportError, AttributeError):  # pragma: no cover - another numpy layout
    _eigvalsh_lo = _inv_gufunc = None


def _eigvalsh(g: NDArray[np.float64]) -> NDArray[np.float64]:
    """np.linalg.eigvalsh of a small finite symmetric float matrix (same LAPACK call)."""
    if _eigvalsh_lo is None:  # pragma: no cover
        return np.linalg.eigvalsh(g)
    # a failed LAPACK call gives NaN (eig[0] > 0 is then False: treated as singular)
    return _eigvalsh_lo(g, signature="d->d")


def _inv(g: NDArray[np.float64]) -> NDArray[np.float64]:
    """np.linalg.inv of a small, well-conditioned float matrix (same LAPACK call)."""
    if _inv_gufunc is None:  # pragma: no cover
        return np.linalg.inv(g)
    return _inv_gufunc(g, signature="d->d")


def _solve_gram(
    gram: NDArray[np.float64], n_rows: int, names: tuple[str, ...] | None
) -> LeastSquaresResult | None:
    """:func:`solve_gram` on checked arguments (a square float Gram, n_rows > n).

    The elementwise steps run in small compiled calls around the two LAPACK
    calls and the two products (same operations in the same order as the numpy
    expressions they replace, so the results are the same to the bit): at 1e4
    samples the dozen small numpy calls cost more than the ARX sums themselves.
    """
    core = _gram_core(gram, n_rows, names)
    if core is None:
        return None
    theta_s, cov_s, scale, rss, sigma2, condition = core
    cov = _covariance(cov_s, scale, sigma2)
    return LeastSquaresResult(theta_s / scale, cov, rss, n_rows, condition, "gram")


def _gram_core(
    gram: NDArray[np.float64], n_rows: int, names: tuple[str, ...] | None
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float, float,
           float] | None:
    """Scaled θ, scaled covariance factor, scale, RSS, σ̂² and condition (or None).

    The steps of :func:`_solve_gram` up to the unscaling, for a caller (ARX)
    that unscales, rearranges and flips signs in one compiled call of its own.
    """
    n = gram.shape[0] - 1
    if type(gram) is not np.ndarray or gram.dtype != np.float64 or not gram.flags.c_contiguous:
        gram = np.ascontiguousarray(gram, dtype=np.float64)
    g, scale, finite, positive = _scaled(gram)
    if not finite:
        raise DataError(
            "the Gram matrix has non-finite entries: the signals are too large for their "
            "squares to be summed in double precision (beyond about 1e150), or hold NaN. "
            "Rescale the channels (calibrate them to SI units)"
        )
    if not positive:  # scale.min() > 0, decided in the compiled call
        _check_columns(scale, names)
    eig = _eigvalsh(g)
    # Python floats: the same IEEE division and correctly rounded square root as
    # float(np.sqrt(eig[-1] / eig[0])), without numpy's scalar overhead (NaN: inf)
    eig_lo, eig_hi = float(eig[0]), float(eig[-1])
    condition = math.sqrt(eig_hi / eig_lo) if eig_lo > 0 else math.inf
    if condition > RANK_COND_LIMIT:
        raise _rank_error(condition, names)
    if condition > GRAM_COND_LIMIT:
        return None
    # g is small (n ≤ a few dozen) and, scaled, well conditioned (κ ≤ GRAM_COND_LIMIT²):
    # its inverse is the covariance factor and gives θ in one product (numpy's LAPACK
    # call costs microseconds; scipy's checked wrappers cost more than the fit at 1e4).
    # RSS = yᵀy − θᵀΦᵀy; cancellation limits it to about ε·yᵀy absolute, which only
    # matters for noise-free data where σ̂² is not used.
    cov_s, rhs = _symmetrised(gram, scale, _inv(g))
    theta_s = cov_s @ rhs
    rss = max(float(gram[n, n] - theta_s @ rhs), 0.0)
    sigma2 = rss / max(n_rows - n, 1)
    return theta_s, cov_s, scale, rss, sigma2, condition


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _scaled(gram):  # type: ignore[no-untyped-def]  # pragma: no cover
    # scale = √diag(Φᵀ Φ), g = (ΦᵀΦ)/(scale scaleᵀ), whether every entry is finite
    # and whether every scale is > 0 (False for NaN, as `not scale.min() > 0`)
    n = gram.shape[0] - 1
    finite = True
    for i in range(n + 1):
        for j in range(n + 1):
            if not np.isfinite(gram[i, j]):
                finite = False
    scale = np.empty(n)
    positive = True
    for i in range(n):
        scale[i] = np.sqrt(gram[i, i])
        if not scale[i] > 0:
            positive = False
    g = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            g[i, j] = gram[i, j] / (scale[i] * scale[j])
    return g, scale, finite, positive


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _symmetrised(gram, scale, inv):  # type: ignore[no-untyped-def]  # pragma: no cover
    # cov_s = (inv + invᵀ)/2 and rhs = Φᵀy/scale, as 0.5 * (c + c.T) and gram[:n, n] / scale
    n = scale.size
    cov_s = np.empty((n, n))
    rhs = np.empty(n)
    for i in range(n):
        rhs[i] = gram[i, n] / scale[i]
        for j in range(n):
            cov_s[i, j] = 0.5 * (inv[i, j] + inv[j, i])
    return cov_s, rhs


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _covariance(cov_s, scale, sigma2):  # type: ignore[no-untyped-def]  # pragma: no cover
    # σ̂²·cov_s / (scale scaleᵀ), evaluated as numpy does: (σ̂²·c_ij) / (s_i·s_j)
    n = scale.size
    cov = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            cov[i, j] = sigma2 * cov_s[i, j] / (scale[i] * scale[j])
    return cov


def _names(names: object, n: int) -> tuple[str, ...] | None:
    if names is None:
        return None
    listed = as_str_list("names", names)
    if len(listed) != n:
        raise DataError(f"names needs one entry per column ({n}), got {len(listed)}")
    return tuple(listed)


def _check_magnitude(phi: NDArray[np.float64], y: NDArray[np.float64]) -> None:
    # Squares beyond ~1e308 overflow and below ~1e-308 underflow: either turns the column
    # scaling into inf or 0 and the answer into nonsense (or a LinAlgError).
    check_magnitude("regressor matrix phi", [phi])
    check_magnitude("left-hand side y", [y])


def _check_rows(n_rows: int, n: int) -> None:
    if n_rows <= n:
        raise DataError(
            f"least squares with {n} parameters needs more than {n} equations, got {n_rows}; "
            "use a longer record or lower orders"
        )


def _check_columns(scale: NDArray[np.float64], names: tuple[str, ...] | None) -> None:
    zero = np.flatnonzero(~(scale > 0))
    if zero.size:
        which = ", ".join(names[k] if names else f"column {k}" for k in zero)
        raise IdentifiabilityError(
            f"regressor {which} is identically zero: the signal is not exciting the model "
            "at all; check the channel mapping and the excitation"
        )


def _triangular_condition(r: NDArray[np.float64]) -> float:
    s = np.linalg.svd(r, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else np.inf


def _rank_error(condition: float, names: tuple[str, ...] | None) -> IdentifiabilityError:
    cols = f" (columns: {', '.join(names)})" if names else ""
    return IdentifiabilityError(
        f"the regressor matrix is rank deficient (scaled condition number {condition:.3g}"
        f"{cols}): the input is not persistently exciting for these orders. Use a richer "
        "input (PRBS, multisine) or lower orders"
    )


def damped_step(h: NDArray[np.float64], g: NDArray[np.float64],
                lam: float) -> NDArray[np.float64]:
    """Solve (H + λ·diag H) Δ = g after equilibration (an LM step).

    ``H`` is a Gauss–Newton matrix JᵀJ, ``g`` the matching gradient term;
    scaling by √diag H first makes λ relative to each parameter's curvature
    (Marquardt's choice).  A singular system falls back to least squares.
    """
    s = np.sqrt(np.clip(np.diag(h), 0.0, None))
    s[~(s > 0)] = 1.0
    hs = h / np.outer(s, s)
    if lam:
        hs = hs + lam * np.eye(h.shape[0])
    try:
        chol = linalg.cho_factor(hs, check_finite=False)
        return linalg.cho_solve(chol, g / s, check_finite=False) / s
    except linalg.LinAlgError:
        return np.linalg.lstsq(hs, g / s, rcond=1e-12)[0] / s
