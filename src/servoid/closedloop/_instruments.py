"""Closed-loop IV: candidate instrument sets from the reference and the automatic choice.

Closed-loop IV (:func:`servoid.estimate.fit_iv` with ``instrument="r"``)
replaces the plant input in its instruments by ``ū``, the input's part
driven by the reference: an auxiliary ARX(n, n + 1) model r → u simulated
from r.  Any filter of r gives valid instruments (r is uncorrelated with
the loop noise); the filter decides only how strongly they are correlated
with the regressors ``[y(t−1)…, u(t−nk)…]``.  A filter that is too rich for
a slowly excited loop (a PRBS whose bit is much longer than the loop's
settling) can make the instruments nearly collinear, and the IV refuses
the record although another filter of the same reference carries the
information.

:func:`choose_instruments` therefore fits the plant with a few filters —
the default auxiliary order, the plain lags of r (order 0) and short and
long auxiliary models — and keeps the one whose instruments are the
strongest: the largest *smallest canonical correlation* between the
instruments ``[x(t−1)…, ū(t−nk)…]`` (``x = B̂/Â ū``, the candidate's own
noise-free output) and the regressors.  The weakest direction governs both
the size of the covariance and how far the IV estimate is pulled toward
least squares by a finite record (weak instruments: Staiger & Stock,
*Econometrica* 65(3), 1997).  Every candidate that fits is a consistent
estimate of the same plant, so two of them further apart than 4σ of their
difference say that the record does not carry the parameters: the estimate
then does not claim consistency.

The delay of the instruments is the auxiliary model's own: its numerator
starts at lag 0 (a controller may pass r through directly) and has n + 1
taps, so a loop delay of up to n samples from r to u is inside every
candidate but the plain lags; a separate delay shift adds nothing to that.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .._errors import IdentifiabilityError, ServoidWarning
from .._lazy import signal as sps
from ..data import Experiment, ExperimentSet, as_segments
from ..estimate import Covariance, Estimate, fit_arx, fit_iv

__all__ = ["AUXILIARY", "Candidate", "choose_instruments", "describe"]

#: Auxiliary orders tried, the default (None) first: 0 is the plain lags of r.
AUXILIARY = (None, 0, 2, 4, 30)
#: Candidates whose strength is within this share of the strongest count as tied:
#: the first of them in AUXILIARY is kept.
_TIE = 0.02
#: Two candidates further apart than this [σ of their difference] disagree.
_DISAGREE = 4.0


@dataclass(frozen=True)
class Candidate:
    """One instrument set tried: its auxiliary order, estimate and strength."""

    order: int | None  # the auxiliary order asked for (None: fit_iv's default)
    estimate: Estimate | None  # None when the IV refused these instruments
    strength: float  # smallest canonical correlation, instruments vs regressors
    refusal: str = ""

    @property
    def used_order(self) -> int:
        """The auxiliary order that was used."""
        if self.estimate is not None:
            return int(self.estimate.options["auxiliary_order"])
        return -1 if self.order is None else self.order

    @property
    def label(self) -> str:
        """The instrument set in words."""
        n = self.used_order
        if n == 0:
            return "the plain lags of r"
        if n < 0:
            return "r through the default auxiliary ARX model r → u"
        return f"r through an ARX({n}, {n + 1}) model of r → u"


def choose_instruments(
    data: Experiment | ExperimentSet, na: int, nb: int, nk: int, *, r_name: str,
    u_name: str, y_name: str, output: str | None, iterations: int, covariance: Covariance,
) -> tuple[Candidate, list[Candidate], str | None]:
    """Fit closed-loop IV with each candidate instrument set and keep the strongest.

    Returns
    -------
    chosen : Candidate
        The candidate with the strongest instruments (see the module notes).
    candidates : list of Candidate
        Every candidate tried, refused ones included.
    disagreement : str or None
        Why the record does not carry the parameters when two fitted
        candidates differ beyond 4σ, else None.

    Raises
    ------
    IdentifiabilityError
        Every candidate refused: the first refusal (the default set's).
    """
    segments = as_segments(data)
    signals = [tuple(np.asarray(seg[n], dtype=float) for n in (r_name, u_name, y_name))
               for seg in segments]
    dt = segments[0].dt
    first_error: IdentifiabilityError | None = None
    candidates: list[Candidate] = []
    seen: set[int] = set()
    for order in AUXILIARY:
        try:
            est = fit_iv(data, na, nb, nk, instrument="r", output=output, iterations=iterations,
                         covariance=covariance, auxiliary_order=order)
        except IdentifiabilityError as exc:
            if "uncorrelated" not in str(exc):
                raise
            first_error = first_error or exc
            candidates.append(Candidate(order, None, 0.0, str(exc)))
            continue
        used = int(est.options["auxiliary_order"])
        if used in seen:  # the default order is one of the others
            continue
        seen.add(used)
        strength = _strength(signals, dt, est, na, nb, nk, used)
        candidates.append(Candidate(order, est, strength))
    fitted = [c for c in candidates if c.estimate is not None]
    if not fitted:
        assert first_error is not None
        raise first_error
    best = max(c.strength for c in fitted)
    chosen = next(c for c in fitted if c.strength >= (1.0 - _TIE) * best)
    return chosen, candidates, _disagreement(chosen, fitted)


def describe(chosen: Candidate, candidates: Sequence[Candidate]) -> str:
    """Which instrument set was chosen and why, in one sentence."""
    others = []
    for c in candidates:
        if c is chosen:
            continue
        others.append(f"{c.label}: refused (nearly uncorrelated)" if c.estimate is None
                      else f"{c.label}: {c.strength:.3g}")
    return (f"instruments: {chosen.label}, chosen as the strongest of the "
            f"{len(candidates)} filters of r tried (smallest canonical correlation with the "
            f"regressors {chosen.strength:.3g}" + "".join(f"; {o}" for o in others) + ")")


def _disagreement(chosen: Candidate, fitted: Sequence[Candidate]) -> str | None:
    """The sentence for two consistent estimates of the plant that differ beyond 4σ."""
    assert chosen.estimate is not None
    theta = np.asarray(chosen.estimate.parameters)
    var = np.diag(chosen.estimate.covariance)
    worst, who = 0.0, None
    for c in fitted:
        if c is chosen:
            continue
        assert c.estimate is not None
        gap = np.abs(np.asarray(c.estimate.parameters) - theta) / np.sqrt(
            var + np.diag(c.estimate.covariance))
        if float(np.max(gap)) > worst:
            worst, who = float(np.max(gap)), c
    if who is None or worst <= _DISAGREE:
        return None
    return (f"closed-loop IV with instruments from {chosen.label} and from {who.label} "
            f"differ by {worst:.3g} σ, though both are consistent estimates of the same plant: "
            "the reference carries too little information at the plant's own frequencies for "
            "the intervals to hold. Raise the reference's excitation (a faster PRBS clock, a "
            "larger amplitude) or lower the orders")


def _strength(signals: Sequence[tuple[NDArray[np.float64], ...]], dt: float, est: Estimate,
              na: int, nb: int, nk: int, order: int) -> float:
    """Smallest canonical correlation of the candidate's instruments with the regressors."""
    ubars = _reference_part(signals, dt, order)
    a = _stable(np.concatenate([[1.0], np.asarray(est.parameters[:na], dtype=float)]))
    b = np.concatenate([np.zeros(nk), np.asarray(est.parameters[na:na + nb], dtype=float)])
    first = max(na, nk + nb - 1, 1)
    phis, zs = [], []
    for (_, u, y), ubar in zip(signals, ubars, strict=True):
        if y.size <= first + 1:
            continue
        rows = np.arange(first, y.size)
        x = sps.lfilter(b, a, ubar) if na else np.zeros(y.size)
        phis.append(np.column_stack([y[rows - j] for j in range(1, na + 1)]
                                    + [u[rows - nk - j] for j in range(nb)]))
        zs.append(np.column_stack([x[rows - j] for j in range(1, na + 1)]
                                  + [ubar[rows - nk - j] for j in range(nb)]))
    if not zs:
        return 0.0
    return _smallest_canonical(np.vstack(phis), np.vstack(zs))


def _reference_part(signals: Sequence[tuple[NDArray[np.float64], ...]], dt: float,
                    order: int) -> list[NDArray[np.float64]]:
    """ū = B/A r per segment, from an ARX(order, order + 1) fit of r → u (delay 0)."""
    pieces = [Experiment.from_arrays(dt, u=r, y=u) for r, u, _ in signals]
    exp: Experiment | ExperimentSet = pieces[0] if len(pieces) == 1 else ExperimentSet(
        tuple(pieces))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        aux = fit_arx(exp, order, order + 1, 0)
    a = _stable(np.concatenate([[1.0], np.asarray(aux.parameters[:order], dtype=float)]))
    b = np.asarray(aux.parameters[order:], dtype=float)
    return [sps.lfilter(b, a, r) for r, _, _ in signals]


def _stable(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """A monic polynomial in q⁻¹ with its roots outside the unit circle reflected inside."""
    if a.size == 1:
        return a
    roots = np.roots(a)
    out = np.abs(roots) > 1.0
    roots[out] = 1.0 / np.conj(roots[out])
    return np.real(np.poly(roots))


def _smallest_canonical(phi: NDArray[np.float64], z: NDArray[np.float64]) -> float:
    """The smallest canonical correlation between the columns of phi and of z."""
    def basis(m: NDArray[np.float64]) -> NDArray[np.float64]:
        m = m - m.mean(axis=0)
        scale = np.sqrt(np.sum(m * m, axis=0))
        scale[scale == 0] = 1.0
        left, sing, _ = np.linalg.svd(m / scale, full_matrices=False)
        return left[:, sing > 1e-10 * max(float(sing[0]), 1e-300)]

    q_phi, q_z = basis(phi), basis(z)
    if q_phi.shape[1] < phi.shape[1] or q_z.shape[1] < z.shape[1]:
        return 0.0
    return float(np.linalg.svd(q_phi.T @ q_z, compute_uv=False)[-1])
