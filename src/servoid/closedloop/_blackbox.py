"""Black-box plant models from closed-loop records with an unknown controller.

With the loop ``u = C(r − y)``, ``y = G u + v`` the plant input is
``u = S·C r − S·C v`` (S = 1/(1 + G C)): its noise-free part ``u_r = S·C r``
is driven by the reference alone, and every method here uses r to reach it:

- :func:`fit_two_stage` — the two-stage method (Van den Hof & Schrama,
  *Automatica* 29(6), 1993): a long FIR model of the map r → u gives
  ``û_r``; an OE (or BJ) model from ``û_r`` to y is then fitted as in open
  loop, since ``y = G û_r + S v`` up to the small stage-1 error and S·v is
  uncorrelated with r.  With ``projection=True`` the FIR is two-sided
  (non-causal), the projection method of Forssell & Ljung (*IEEE TAC*
  45(11), 2000), which also copes with a non-linear controller.
- :func:`fit_cliv` — closed-loop instrumental variables, instruments built
  from r (:func:`servoid.estimate.fit_iv` with ``instrument="r"``).
- the direct approach is :func:`servoid.estimate.fit_bj` on (u, y): with a
  noise model that can describe v it is consistent and efficient whatever
  the controller (Ljung, *System Identification*, 2nd ed., §13.4).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import as_bool, as_int
from .._errors import DataError, ServoidWarning, check_option
from .._warn import warn
from ..data import Experiment, ExperimentSet, as_segments
from ..estimate import Covariance, Estimate, fit_bj, fit_iv, fit_oe
from ._channels import aic_order, check_excites, ls_fit, output_name, reference_name, single_name

__all__ = ["fit_cliv", "fit_two_stage"]

Structure = Literal["oe", "bj"]

#: Longest stage-1 FIR the default order search tries [samples].
_MAX_STAGE1 = 100
#: Rows per stage-1 coefficient below which the search stops growing.
_ROWS_PER_TAP = 20
#: Share of var(u) the reference must explain before a warning.
_WEAK_REFERENCE = 0.05


def fit_two_stage(
    data: Experiment | ExperimentSet,
    nb: int,
    nf: int,
    nk: int = 1,
    *,
    stage1_order: int | None = None,
    projection: bool = False,
    structure: Structure = "oe",
    nc: int = 1,
    nd: int = 1,
    output: str | None = None,
    multistart: int = 0,
    rng: np.random.Generator | int | None = None,
    max_iter: int = 100,
    tol: float = 1e-9,
) -> Estimate:
    """Fit the plant by the two-stage (projection) method.

    Stage 1 fits ``u(t) = Σ_k s_k r(t − k)`` by least squares (k = 0…L − 1,
    or −(L − 1)…L − 1 with `projection`) and simulates ``û_r = Ŝ r``; stage
    2 fits ``y = B/F û_r(t − nk)`` (+ ``C/D e`` for ``"bj"``) with
    :func:`~servoid.estimate.fit_oe` / :func:`~servoid.estimate.fit_bj`.
    See the module notes (Van den Hof & Schrama 1993; Forssell & Ljung
    2000).  For ``"oe"`` the covariance is the coloured-noise sandwich
    (the stage-2 residual is S·v, not white); the stage-1 error is not
    counted in it.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Closed-loop record(s) with one reference r, one plant input u and
        the output y.  The controller need not be known.
    nb : int
        Number of B coefficients of the plant.
    nf : int
        Order of F (the plant poles).
    nk : int
        Plant delay [samples].
    stage1_order : int, optional
        Length L of the stage-1 FIR; default: AIC within 1…100 (fewer for
        short records).  It must cover the settling of the map r → u.
    projection : bool
        Two-sided FIR (the projection method) instead of a causal one.
    structure : {"oe", "bj"}
        Stage-2 model: output error, or Box–Jenkins with noise orders
        `nc`, `nd`.
    nc, nd : int
        Orders of C and D for ``structure="bj"``.
    output : str, optional
        Output channel name when there are several.
    multistart, rng, max_iter, tol
        Passed to the stage-2 estimator (see :func:`servoid.estimate.fit_pem`).

    Returns
    -------
    Estimate
        Method ``"two-stage"``; parameters ``b0…, f1…`` (then ``c1…, d1…``
        for BJ); ``options`` add the stage-1 order, lags, and the share of
        var(u) the reference explains.

    Raises
    ------
    DataError
        No reference or input channel, or too few samples.
    IdentifiabilityError
        A constant reference or input.

    Examples
    --------
    >>> from servoid.bench import simulate_lti_loop
    >>> from servoid.models import TransferFunction
    >>> plant = TransferFunction([4.0], [1.0, 2.0])
    >>> pi = TransferFunction([0.6, -0.5], [1.0, -1.0], 0.1)
    >>> r = np.repeat(np.sign(np.random.default_rng(1).standard_normal(1000)), 3)
    >>> exp = simulate_lti_loop(plant, pi, r, 0.1, noise_std=0.05, rng=2)
    >>> est = fit_two_stage(exp, nb=1, nf=1)
    >>> round(float(est.model.transfer_function().dc_gain()), 1)
    2.0
    """
    check_option("structure", structure, ("oe", "bj"))
    projection = as_bool("projection", projection)
    nb = as_int("nb", nb, minimum=1)
    nf = as_int("nf", nf, minimum=0)
    nk = as_int("nk", nk, minimum=0)
    segments = as_segments(data)
    r_name = reference_name(data, "the two-stage method")
    first = segments[0]
    u_name = single_name(first, "u", None, "plant input")
    y_name = output_name(first, output)
    rs = [np.asarray(seg[r_name], dtype=float) for seg in segments]
    us = [np.asarray(seg[u_name], dtype=float) for seg in segments]
    ys = [np.asarray(seg[y_name], dtype=float) for seg in segments]
    check_excites(r_name, rs, "r")
    check_excites(u_name, us, "u")
    ur, info = _stage1(rs, us, stage1_order, projection)
    if info["explained"] < _WEAK_REFERENCE:
        warn(
            f"the reference explains only {100 * info['explained']:.2g} % of the variance of "
            f"{u_name!r}: the noise-free input û_r is weak, so the plant estimate will be "
            "poor. Raise the reference excitation",
            ServoidWarning,
        )
    stage2 = ExperimentSet(tuple(
        Experiment.from_arrays(seg.dt, u=x, y=y, names={"u": u_name, "y": y_name}, t0=seg.t0,
                               name=seg.name)
        for seg, x, y in zip(segments, ur, ys, strict=True)
    ))
    stage2_data: Experiment | ExperimentSet = stage2[0] if len(stage2) == 1 else stage2
    pem = {"multistart": multistart, "rng": rng, "max_iter": max_iter, "tol": tol}
    if structure == "oe":
        # the OE fit's own covariance is already the coloured-noise sandwich
        est = fit_oe(stage2_data, nb, nf, nk, covariance="robust", **pem)  # type: ignore[arg-type]
        cov = est.covariance
        note = (f"sandwich, AR({est.options['covariance_ar_order']}) residual spectrum; "
                "stage-1 error not counted")
    else:
        est = fit_bj(stage2_data, nb, nc, nd, nf, nk, **pem)  # type: ignore[arg-type]
        cov, note = est.covariance, "bj (noise model); stage-1 error not counted"
    return dataclasses.replace(
        est,
        covariance=cov,
        method="two-stage",
        options={
            **est.options,
            "structure": structure,
            "reference": r_name,
            "input": u_name,
            "stage1_order": info["order"],
            "stage1_lags": info["lags"],
            "projection": projection,
            "reference_explains": info["explained"],
            "covariance": note,
        },
    )


def fit_cliv(
    data: Experiment | ExperimentSet,
    na: int,
    nb: int,
    nk: int = 1,
    *,
    output: str | None = None,
    iterations: int = 1,
    covariance: Covariance = "auto",
) -> Estimate:
    """Fit the plant by closed-loop IV, instruments from r.

    A thin closed-loop front end of :func:`servoid.estimate.fit_iv` with
    ``instrument="r"`` (Söderström & Stoica 1983; Gilson & Van den Hof,
    *Automatica* 41(2), 2005): the instruments are built from r alone, so
    the estimate is consistent with an unknown controller and any noise
    colour.  The model is the plant; it carries no noise model.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Closed-loop record(s) with one reference r, one plant input u and
        the output y.
    na : int
        Number of A coefficients after the leading 1.
    nb : int
        Number of B coefficients.
    nk : int
        Plant delay [samples].
    output : str, optional
        Output channel name when there are several.
    iterations : int
        Refinement passes of the IV (see :func:`~servoid.estimate.fit_iv`).
    covariance : {"auto", "white", "robust"}
        As in :func:`~servoid.estimate.fit_iv`: ``"auto"`` is the sandwich
        with the residual's own autocovariance, right for any noise colour.

    Returns
    -------
    Estimate
        Method ``"cliv"``; parameters ``a1…, b0…`` as in
        :func:`~servoid.estimate.fit_arx`; ``options["covariance"]`` says
        which covariance was used.

    Raises
    ------
    DataError
        No reference or input channel, or too few samples.
    IdentifiabilityError
        A constant reference or input.
    """
    segments = as_segments(data)
    r_name = reference_name(data, "closed-loop IV")
    check_excites(r_name, [np.asarray(seg[r_name]) for seg in segments], "r")
    single_name(segments[0], "u", None, "plant input")
    est = fit_iv(data, na, nb, nk, instrument="r", output=output, iterations=iterations,
                 covariance=covariance)
    return dataclasses.replace(est, method="cliv", options={**est.options, "reference": r_name})


def _stage1(
    rs: Sequence[NDArray[np.float64]],
    us: Sequence[NDArray[np.float64]],
    order: int | None,
    projection: bool,
) -> tuple[list[NDArray[np.float64]], dict[str, object]]:
    """FIR r → u by least squares; return û_r per segment and a summary."""
    shortest = min(r.size for r in rs)
    total = sum(r.size for r in rs)
    if order is None:
        per_tap = 2 if projection else 1
        l_max = int(min(_MAX_STAGE1, max(total // (_ROWS_PER_TAP * per_tap), 1)))
    else:
        l_max = as_int("stage1_order", order, minimum=1)
    # lags interleaved 0, 1, −1, 2, −2, … so every order is a prefix of the columns
    lags = [0]
    for k in range(1, l_max):
        lags += [k, -k] if projection else [k]
    lead = l_max - 1 if projection else 0
    if shortest <= l_max + lead + len(lags):
        raise DataError(
            f"the stage-1 FIR of length {l_max} needs segments of more than "
            f"{l_max + lead + len(lags)} samples, got {shortest}; use a longer record or a "
            "smaller stage1_order"
        )
    phi, target, means = [], [], []
    for r, u in zip(rs, us, strict=True):
        r0, u0 = r - r.mean(), u - u.mean()
        rows = np.arange(l_max - 1, r.size - lead)
        phi.append(np.column_stack([r0[rows - k] for k in lags]))
        target.append(u0[rows])
        means.append((r.mean(), u.mean()))
    x, t = np.vstack(phi), np.concatenate(target)
    sizes = [2 * n - 1 if projection else n for n in range(1, l_max + 1)]
    n = l_max if order is not None else aic_order(x, t, sizes) + 1
    k_cols = sizes[n - 1]
    coef, resid, _ = ls_fit(x[:, :k_cols], t)
    explained = float(1.0 - (resid @ resid) / max(float(t @ t), 1e-300))
    used = lags[:k_cols]
    ur = []
    for r, (r_mean, u_mean) in zip(rs, means, strict=True):
        r0 = r - r_mean
        # Σ_k s_k r(t − k) with r = 0 outside the record, for negative (future) lags too
        back = max(used)
        ahead = -min(used)
        kernel = np.zeros(back + ahead + 1)
        for c, k in zip(coef, used, strict=True):
            kernel[k + ahead] = c
        full = np.convolve(r0, kernel)
        ur.append(u_mean + full[ahead: ahead + r.size])
    return ur, {"order": int(n), "lags": [int(min(used)), int(max(used))],
                "explained": explained}
