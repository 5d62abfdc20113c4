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
import warnings
from collections.abc import Sequence
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .._checks import as_bool, as_int
from .._errors import DataError, IdentifiabilityError, ServoidError, ServoidWarning, check_option
from .._warn import warn
from ..data import Experiment, ExperimentSet, as_segments
from ..estimate import Covariance, Estimate, fit_bj, fit_iv, fit_oe
from ._channels import aic_order, check_excites, ls_fit, output_name, reference_name, single_name
from ._instruments import AUXILIARY, choose_instruments, describe
from ._linearity import interval_check, is_noise_free
from ._overid import LEVEL, overidentification
from ._stagecov import Stage1, two_stage_covariance

__all__ = ["fit_cliv", "fit_two_stage"]

Structure = Literal["oe", "bj"]

#: Longest stage-1 FIR the default order search tries [samples].
_MAX_STAGE1 = 100
#: Rows per stage-1 coefficient below which the search stops growing.
_ROWS_PER_TAP = 20
#: A pole this far beyond the unit circle (|z| − 1) counts as unstable.
_UNSTABLE_MARGIN = 1e-3
#: Two-stage and CLIV estimates further apart than this [σ of the difference] disagree.
_DISAGREE = 4.0
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
        var(u) the reference explains.  ``options["consistent"]`` is False,
        with the reasons in ``options["broken_assumptions"]`` and a warning,
        on an unstable plant, when the estimate and closed-loop IV disagree
        beyond 4σ, or when the covariance changes by more than ×1.4 one σ
        away or at the closed-loop IV estimate (too little information for
        the intervals, :mod:`servoid.closedloop._linearity`).

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
    first_stage = _stage1(rs, us, stage1_order, projection)
    explained = first_stage.explained
    if explained < _WEAK_REFERENCE:
        warn(
            f"the reference explains only {100 * explained:.2g} % of the variance of "
            f"{u_name!r}: the noise-free input û_r is weak, so the plant estimate will be "
            "poor. Raise the reference excitation",
            ServoidWarning,
        )
    stage2 = ExperimentSet(tuple(
        Experiment.from_arrays(seg.dt, u=x, y=y, names={"u": u_name, "y": y_name}, t0=seg.t0,
                               name=seg.name)
        for seg, x, y in zip(segments, first_stage.ur, ys, strict=True)
    ))
    stage2_data: Experiment | ExperimentSet = stage2[0] if len(stage2) == 1 else stage2
    pem = {"multistart": multistart, "rng": rng, "max_iter": max_iter, "tol": tol}
    # an unstable plant has an unstable OE predictor: the stage-2 search cannot reach it
    check = _cliv_check(data, nf, nb, nk, y_name)
    unstable = check[0] if check is not None else None
    if structure == "oe":
        with warnings.catch_warnings():
            # identifiability is judged below with the covariance that counts stage 1
            warnings.filterwarnings("ignore", ".*not all identifiable", ServoidWarning)
            est = fit_oe(stage2_data, nb, nf, nk, covariance="robust", initial="zero",
                         **pem)  # type: ignore[arg-type]
        b = np.asarray(est.parameters[:nb])
        f = np.concatenate([[1.0], est.parameters[nb:]])
        cov, bandwidth = two_stage_covariance(first_stage, ys, b, f, nk)
        note = (f"two-step sandwich: stage-1 FIR error counted, long-run covariance over "
                f"{bandwidth} lags")
    else:
        est = fit_bj(stage2_data, nb, nc, nd, nf, nk, **pem)  # type: ignore[arg-type]
        cov, note = est.covariance, "bj (noise model); stage-1 error not counted"
    broken = []
    also: list[tuple[str, NDArray[np.float64]]] = []
    if unstable is not None:
        broken.append(
            f"the plant is unstable (the closed-loop IV estimate has a pole at |z| = "
            f"{unstable:.3g}), so the output-error predictor of stage 2 is unstable and its "
            "search can only return a stable, biased plant; use method = \"cliv\", or "
            "\"indirect\" with the known controller"
        )
    elif check is not None and structure == "oe":
        # the same plant from CLIV, which has no stage 1: a disagreement beyond both
        # intervals is the stage-1 error showing as dynamics of its own in stage 2
        theta_iv = np.concatenate([check[1][nf:], check[1][:nf]])
        also.append(("the closed-loop IV estimate of the same plant", theta_iv))
        var_iv = np.concatenate([np.diag(check[2])[nf:], np.diag(check[2])[:nf]])
        gap = np.abs(np.asarray(est.parameters) - theta_iv) / np.sqrt(np.diag(cov) + var_iv)
        if float(np.max(gap)) > _DISAGREE:
            broken.append(
                f"the plant of stage 2 and the closed-loop IV estimate of the same orders "
                f"differ by {float(np.max(gap)):.3g} σ: the stage-1 FIR r → u (order "
                f"{first_stage.order}) leaves an error that stage 2 explains with dynamics "
                "of its own; use method = \"cliv\" or the direct Box–Jenkins fit"
            )
    if not broken and structure == "oe" and not is_noise_free([est.residuals], ys):
        names = [f"b{j}" for j in range(nb)] + [f"f{j}" for j in range(1, nf + 1)]
        _, verdict = interval_check(
            np.asarray(est.parameters), cov,
            lambda th: _stage2_covariance(first_stage, ys, th, nb, nk), names, also)
        if verdict is not None:
            broken.append(verdict)
    if broken:
        warn(f"the two-stage estimate is not consistent on this record: {broken[0]}",
             ServoidWarning)
    return dataclasses.replace(
        est,
        covariance=cov,
        method="two-stage",
        options={
            **est.options,
            "structure": structure,
            "reference": r_name,
            "input": u_name,
            "stage1_order": first_stage.order,
            "stage1_lags": [min(first_stage.lags), max(first_stage.lags)],
            "projection": projection,
            "reference_explains": explained,
            "covariance": note,
            "consistent": not broken,
            "broken_assumptions": broken,
        },
    )


def _stage2_covariance(stage1: Stage1, ys: Sequence[NDArray[np.float64]],
                       theta: NDArray[np.float64], nb: int, nk: int
                       ) -> NDArray[np.float64] | None:
    """The two-stage covariance at θ, or None where the OE model is unstable."""
    f = np.concatenate([[1.0], theta[nb:]])
    if np.max(np.abs(np.roots(f)), initial=0.0) >= 1.0:
        return None
    return two_stage_covariance(stage1, ys, theta[:nb], f, nk)[0]


def _cliv_check(
    data: Experiment | ExperimentSet, nf: int, nb: int, nk: int, y_name: str,
) -> tuple[float | None, NDArray[np.float64], NDArray[np.float64]] | None:
    """Closed-loop IV of the same plant: (unstable pole radius or None, θ, covariance)."""
    if nf == 0:
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ServoidWarning)
            iv = fit_iv(data, nf, nb, nk, instrument="r", output=y_name)
    except ServoidError:
        return None
    theta = np.asarray(iv.parameters, dtype=float)
    radius = float(np.max(np.abs(np.roots(np.concatenate([[1.0], theta[:nf]])))))
    return (radius if radius > 1.0 + _UNSTABLE_MARGIN else None), theta, iv.covariance


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

    The filter of r behind the instruments is chosen on the data: the
    default auxiliary ARX model r → u, the plain lags of r and auxiliary
    models of orders 2, 4 and 30 are tried, and the strongest instruments
    (largest smallest canonical correlation with the regressors) are kept
    (:mod:`servoid.closedloop._instruments`).  When two of them give
    estimates more than 4σ apart the record does not carry the parameters
    and the estimate does not claim consistency.

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
        which covariance was used, ``options["instruments"]`` which filter
        of r made the instruments and ``options["instrument_choice"]`` why;
        ``options["consistent"]`` is False, with the reason in
        ``options["broken_assumptions"]`` and a warning, when the
        instrument sets disagree.

    Raises
    ------
    DataError
        No reference or input channel, or too few samples.
    IdentifiabilityError
        A constant reference or input, or instruments from r that cannot
        tell the regressors apart with any of the filters tried: the message names the regressors whose
        instruments fail (the direction of the smallest canonical
        correlation between the regressors and the lags of r).
    """
    segments = as_segments(data)
    r_name = reference_name(data, "closed-loop IV")
    check_excites(r_name, [np.asarray(seg[r_name]) for seg in segments], "r")
    u_name = single_name(segments[0], "u", None, "plant input")
    y_name = output_name(segments[0], output)
    try:
        chosen, candidates, disagreement = choose_instruments(
            data, na, nb, nk, r_name=r_name, u_name=u_name, y_name=y_name, output=output,
            iterations=iterations, covariance=covariance)
    except IdentifiabilityError as exc:
        if "uncorrelated" not in str(exc):
            raise
        weakest, corr = _weakest_regressors(segments, r_name, u_name, y_name, na, nb, nk)
        raise IdentifiabilityError(
            f"closed-loop IV failed: its instruments, the reference {r_name!r} delayed and "
            f"filtered through the model's own simulation, are nearly uncorrelated with the "
            f"regressors (lags of u and y) for na = {na}, nb = {nb} with each of the "
            f"{len(AUXILIARY)} filters of the reference it tries ({exc}). The instruments "
            f"that fail are those for {_listed(weakest)}: no filter of the reference "
            f"moves that combination of regressors apart from the others (canonical "
            f"correlation {corr:.2g} with the lags of {r_name!r}). The reference moves the "
            "loop too little at the plant's own frequencies: raise the reference's excitation "
            "(a faster PRBS clock, a larger amplitude), lower the orders, or, with the "
            "controller known, use method = \"indirect\""
        ) from exc
    est = chosen.estimate
    assert est is not None
    broken = [] if disagreement is None else [disagreement]
    signals = [tuple(np.asarray(seg[n], dtype=float) for n in (r_name, u_name, y_name))
               for seg in segments]
    overid = overidentification(signals, np.asarray(est.parameters, dtype=float), na, nb, nk)
    if overid is not None and overid.rejects:
        broken.append(
            f"the instruments appear correlated with the noise: with {overid.dof} more lags "
            f"of {r_name!r} than parameters, the over-identification test rejects them "
            f"(Sargan J = {overid.statistic:.3g}, p = {overid.p_value:.2g} < {LEVEL:g}). "
            f"The recorded reference {r_name!r} may carry the output's noise (crosstalk "
            "in the acquisition, or a reference computed from the measured output), so "
            "closed-loop IV is biased on this record. With the controller known use "
            "method = \"indirect\"; otherwise fit the direct Box–Jenkins model on the "
            "input and output (servoid.closedloop.fit_direct_bj)")
    for reason in broken:
        warn(f"the closed-loop IV estimate is not consistent on this record: {reason}",
             ServoidWarning)
    return dataclasses.replace(est, method="cliv", options={
        **est.options,
        "reference": r_name,
        "instruments": chosen.label,
        "instrument_choice": describe(chosen, candidates),
        "consistent": not broken,
        "broken_assumptions": broken,
        "overidentification": None if overid is None else overid.to_dict(),
    })


def _listed(names: Sequence[str]) -> str:
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def _weakest_regressors(
    segments: Sequence[Experiment], r_name: str, u_name: str, y_name: str,
    na: int, nb: int, nk: int,
) -> tuple[list[str], float]:
    """The regressors the reference cannot reach, and their canonical correlation with it.

    The smallest canonical correlation between the ARX regressors
    ``[y(t−1)…, u(t−nk)…]`` and the lags 0…L of r bounds what any instrument
    built from r can do; its direction, as weights on the standardised
    regressors, names the ones that fail.
    """
    lags = max(2 * (na + nb), 20)
    first = max(na, nk + nb - 1, lags)
    phis, zs = [], []
    for seg in segments:
        r, u, y = (np.asarray(seg[n], dtype=float) for n in (r_name, u_name, y_name))
        if r.size <= first + 1:
            continue
        rows = np.arange(first, r.size)
        phis.append(np.column_stack([y[rows - j] for j in range(1, na + 1)]
                                    + [u[rows - nk - j] for j in range(nb)]))
        zs.append(np.column_stack([r[rows - j] for j in range(lags + 1)]))
    names = ([f"y(t−{j})" for j in range(1, na + 1)]
             + [f"u(t−{nk + j})" if nk + j else "u(t)" for j in range(nb)])
    if not zs:
        return names, 0.0
    phi = np.vstack(phis)
    phi = phi - phi.mean(axis=0)
    z = np.vstack(zs)
    z = z - z.mean(axis=0)
    scale = np.sqrt(np.sum(phi * phi, axis=0))
    scale[scale == 0] = 1.0
    q_phi, r_phi = np.linalg.qr(phi / scale)
    left, sing, _ = np.linalg.svd(z, full_matrices=False)
    q_z = left[:, sing > 1e-10 * sing[0]]
    a, corr, _ = np.linalg.svd(q_phi.T @ q_z, full_matrices=True)
    # the direction of the smallest canonical correlation, on the standardised regressors
    weights = np.linalg.lstsq(r_phi, a[:, -1], rcond=None)[0]
    weights = np.abs(weights) / max(float(np.max(np.abs(weights))), 1e-300)
    smallest = float(corr[-1]) if corr.size == a.shape[0] else 0.0
    return [n for n, w in zip(names, weights, strict=True) if w >= 0.3], smallest


def _stage1(
    rs: Sequence[NDArray[np.float64]],
    us: Sequence[NDArray[np.float64]],
    order: int | None,
    projection: bool,
) -> Stage1:
    """FIR r → u by least squares: û_r per segment, the regression kept for the covariance."""
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
    phi, target, means, r0s, row_list = [], [], [], [], []
    for r, u in zip(rs, us, strict=True):
        r0, u0 = r - r.mean(), u - u.mean()
        rows = np.arange(l_max - 1, r.size - lead)
        phi.append(np.column_stack([r0[rows - k] for k in lags]))
        target.append(u0[rows])
        means.append(u.mean())
        r0s.append(r0)
        row_list.append(rows)
    x, t = np.vstack(phi), np.concatenate(target)
    sizes = [2 * n - 1 if projection else n for n in range(1, l_max + 1)]
    n = l_max if order is not None else aic_order(x, t, sizes) + 1
    k_cols = sizes[n - 1]
    coef, resid, _ = ls_fit(x[:, :k_cols], t)
    explained = float(1.0 - (resid @ resid) / max(float(t @ t), 1e-300))
    used = tuple(int(k) for k in lags[:k_cols])
    ur, e1 = [], []
    start = 0
    for r0, u_mean, rows in zip(r0s, means, row_list, strict=True):
        # Σ_k s_k r(t − k) with r = 0 outside the record, for negative (future) lags too
        back = max(used)
        ahead = -min(used)
        kernel = np.zeros(back + ahead + 1)
        for c, k in zip(coef, used, strict=True):
            kernel[k + ahead] = c
        full = np.convolve(r0, kernel)
        ur.append(u_mean + full[ahead: ahead + r0.size])
        e1.append(resid[start: start + rows.size])
        start += rows.size
    cols = x[:, :k_cols]
    return Stage1(coef=coef, lags=used, r0=tuple(r0s), rows=tuple(row_list), e1=tuple(e1),
                  ur=tuple(ur), gram=cols.T @ cols, order=int(n), explained=explained)
