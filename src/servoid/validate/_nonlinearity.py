"""Higher-order correlation tests: does a model leave a nonlinearity unexplained?

The input–residual test correlates ε with u; a model that misses a
nonlinearity can pass it, because the part it misses (u², u·y, a
saturation) is uncorrelated with u itself for a symmetric input.  Billings
and Voon (1986, "Correlation based model validity tests for non-linear
models", *Int. J. Control* 44) and Billings and Zhu (1994, "Nonlinear model
validation using correlation tests", *Int. J. Control* 60) test the
residuals against nonlinear functions of the data instead.  Three of their
correlations are tested here, each zero at every lag for a model that has
captured the system:

* ``ε–u²``: ε(t) with u²'(t − τ) = u²(t − τ) − mean(u²), all lags −M…M;
* ``ε²–u²``: ε²'(t) with u²'(t − τ), all lags (a missing nonlinearity that
  changes the residuals' size with the input's);
* ``ε–εu``: ε(t) with (εu)'(t − τ), lags τ = 1…M (terms of the past
  residual and input together, as a NARMAX noise model would have).

**Coloured residuals.**  An output-error model's residuals are the
coloured noise, and the tests assume white ones: ε is first whitened by an
autoregressive model fitted to it (Yule–Walker, order by BIC up to
:data:`MAX_AR`), which keeps it independent of the input when the model is
right and carries a missing nonlinear term through a linear filter when it
is not.  Each correlation is then tested jointly over its lags with the
input–residual statistic of :func:`~servoid.validate.residual_analysis`
(χ² with the covariance of the nonlinear regressor's own correlations),
and the three p-values are combined by Bonferroni: the flag is raised when
one lies below ``(1 − confidence)/3``, so the false-alarm rate on a right
model is at most ``1 − confidence``.

A two-level input (a PRBS) has a u² that is an affine function of u (a
constant for a symmetric one): the two tests on u² would repeat the linear
test and are left out (their p-values are NaN).
The tests assume a symmetric input (zero third moments): the residual of a
wrong *linear* model then stays uncorrelated with u², so the flag points
at a nonlinearity, not at wrong orders.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array, as_bool, as_float, as_int
from .._errors import DataError
from .._lazy import linalg
from ._residuals import residual_analysis

__all__ = ["MAX_AR", "TESTS", "NonlinearityTests", "nonlinearity_tests"]

#: The correlations tested, in order.
TESTS = ("ε–u²", "ε²–u²", "ε–εu")
#: Highest order of the whitening AR model of the residuals.
MAX_AR = 20
#: Relative spread of u² below which the input counts as two-level (u² constant).
_TWO_LEVEL = 1e-6


@dataclass(frozen=True, eq=False)
class NonlinearityTests:
    """Higher-order correlation tests of residuals against the input.

    Attributes
    ----------
    pvalues : mapping of str to float
        p-value of each correlation in :data:`TESTS` (NaN: not testable).
    confidence : float
        Level of the combined decision.
    max_lag : int
        Largest lag M tested [samples].
    whitening_order : int
        Order of the AR model that whitened the residuals (0: already white).
    n_samples : int
        Residuals tested.
    """

    pvalues: Mapping[str, float]
    confidence: float
    max_lag: int
    whitening_order: int
    n_samples: int

    @property
    def tested(self) -> tuple[str, ...]:
        """The correlations that could be tested."""
        return tuple(k for k, p in self.pvalues.items() if not math.isnan(p))

    @property
    def pvalue(self) -> float:
        """The Bonferroni-combined p-value: the smallest times the number tested, ≤ 1."""
        tested = [self.pvalues[k] for k in self.tested]
        if not tested:
            return math.nan
        return min(1.0, min(tested) * len(tested))

    @property
    def detected(self) -> bool:
        """An unmodelled nonlinearity: the combined p-value below 1 − confidence."""
        p = self.pvalue
        return bool(not math.isnan(p) and p < 1.0 - self.confidence)

    @property
    def strongest(self) -> str:
        """The correlation with the smallest p-value ('' when none was tested)."""
        tested = self.tested
        return min(tested, key=lambda k: self.pvalues[k]) if tested else ""

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {"pvalues": {k: (None if math.isnan(v) else float(v))
                            for k, v in self.pvalues.items()},
                "pvalue": None if math.isnan(self.pvalue) else self.pvalue,
                "detected": self.detected, "confidence": self.confidence,
                "max_lag": self.max_lag, "whitening_order": self.whitening_order,
                "n_samples": self.n_samples}

    def __str__(self) -> str:
        parts = ", ".join(f"{k} p = {v:.3g}" for k, v in self.pvalues.items()
                          if not math.isnan(v))
        verdict = "unmodelled nonlinearity" if self.detected else "no nonlinearity left"
        return f"higher-order tests: {verdict} ({parts or 'not testable'})"


def nonlinearity_tests(residuals: ArrayLike, u: ArrayLike, max_lag: int = 25,
                       confidence: float = 0.99, causal: bool = False) -> NonlinearityTests:
    """Test residuals for a nonlinearity the model leaves unexplained.

    Parameters
    ----------
    residuals : array_like, shape (N,)
        Residuals of the model on (preferably validation) data: one-step
        prediction errors, or the simulation error of an output-error model.
    u : array_like, shape (N,) or (N, n_inputs)
        The input(s) over the same samples; each is tested, and the
        decision counts every p-value (Bonferroni).
    max_lag : int
        Largest lag M [samples].
    confidence : float
        Level of the combined decision (0.99: at most 1 % false alarms on a
        right model).
    causal : bool
        Closed loop: test ε–u² and ε²–u² only at lags where the input leads.

    Returns
    -------
    NonlinearityTests

    Notes
    -----
    Time O(N·M) per test (the kernels of the input–residual test) plus an
    AR fit of order ≤ 20 to the residuals.
    """
    e = as_array("residuals", residuals).ravel()
    x = as_array("u", u)
    x = x[:, None] if x.ndim == 1 else x
    if x.shape[0] != e.size:
        raise DataError(f"u has {x.shape[0]} samples but the residuals {e.size}")
    max_lag = as_int("max_lag", max_lag, minimum=1)
    confidence = as_float("confidence", confidence)
    causal = as_bool("causal", causal)
    if not 0.0 < confidence < 1.0:
        raise DataError(f"confidence must lie in (0, 1), e.g. 0.99, got {confidence}")
    keep = np.isfinite(e) & np.all(np.isfinite(x), axis=1)
    e, x = e[keep], x[keep]
    if e.size < 4 * max_lag + 10:
        raise DataError(f"{e.size} residuals are too few for the higher-order tests up to lag "
                        f"{max_lag}; give a longer record")
    white, order = _whiten(e - e.mean(), min(MAX_AR, e.size // 50))
    x = x[order:]
    pvalues: dict[str, float] = {}
    several = x.shape[1] > 1
    for i in range(x.shape[1]):
        suffix = f" (input {i + 1})" if several else ""
        pvalues.update({k + suffix: v for k, v in
                        _three(white, x[:, i], max_lag, confidence, causal).items()})
    return NonlinearityTests(pvalues, confidence, max_lag, order, int(white.size))


def _three(e: NDArray[np.float64], u: NDArray[np.float64], max_lag: int, confidence: float,
           causal: bool) -> dict[str, float]:
    """The three p-values for one input."""
    uc = u - u.mean()
    u2 = uc * uc
    scale = float(np.mean(u2))
    out = dict.fromkeys(TESTS, math.nan)
    lo, hi = float(u.min()), float(u.max())
    two_level = bool(np.all((u == lo) | (u == hi)))  # u² is then affine in u
    if scale > 0.0 and not two_level and float(np.std(u2)) > _TWO_LEVEL * scale:
        z = u2 - scale
        out["ε–u²"] = _pvalue(e, z, max_lag, confidence, causal)
        e2 = e * e
        out["ε²–u²"] = _pvalue(e2 - e2.mean(), z, max_lag, confidence, causal)
    if scale > 0.0 and np.any(e):
        eu = e * uc
        # lags 1…M: ε(t) against (εu)(t − 1 − τ'), τ' = 0…M − 1 (lag 0 shares ε(t) itself)
        out["ε–εu"] = _pvalue(e[1:], (eu - eu.mean())[:-1], max_lag - 1 or 1, confidence,
                              True)
    return out


def _pvalue(e: NDArray[np.float64], z: NDArray[np.float64], max_lag: int, confidence: float,
            causal: bool) -> float:
    if not np.any(e) or not np.any(z):
        return math.nan
    p = residual_analysis(e, z, max_lag=max_lag, confidence=confidence,
                          causal=causal).independence_pvalue
    return float(p)


def _whiten(e: NDArray[np.float64], highest: int) -> tuple[NDArray[np.float64], int]:
    """ε filtered by its AR(p) whitening filter, p by BIC ≤ highest; drops p samples."""
    n = e.size
    if highest < 1 or not np.any(e):
        return e, 0
    r = np.array([float(e[: n - k] @ e[k:]) / n for k in range(highest + 1)])
    if not r[0] > 0.0:
        return e, 0
    best, best_bic, best_a = 0, n * math.log(r[0]), np.zeros(0)
    for p in range(1, highest + 1):
        try:
            a = linalg.solve_toeplitz(r[:p], r[1: p + 1])
        except (np.linalg.LinAlgError, ValueError):
            break
        var = r[0] - float(a @ r[1: p + 1])
        if not var > 0.0:
            break
        bic = n * math.log(var) + p * math.log(n)
        if bic < best_bic:
            best, best_bic, best_a = p, bic, a
    if best == 0:
        return e, 0
    white = e[best:].copy()
    for k in range(best):
        white -= best_a[k] * e[best - 1 - k: n - 1 - k]
    return white, best
