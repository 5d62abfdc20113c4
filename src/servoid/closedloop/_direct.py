"""The direct approach: Box–Jenkins on (u, y), started where the loop cannot mislead it.

With a noise model that can describe the noise, the prediction-error fit of
``y = B/F u + C/D e`` on the plant's own input and output is consistent and
efficient whatever the controller (Ljung, *System Identification*, 2nd ed.,
§13.4).  Its search is what fails in a loop: the default start (IV on u)
is biased by the feedback, and from it the search can stall in a valley.
:func:`fit_direct_bj` therefore also starts from the closed-loop IV
estimate (instruments from r, consistent for any controller) when the
reference is recorded, and keeps the lower cost.

An unstable plant has an unstable Box–Jenkins predictor (it simulates
``B/F u``), so the fit cannot be consistent there; the estimate then says
so (``options["consistent"] = False``) and names the methods that are:
closed-loop IV, or the indirect approach with the known controller.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from .._errors import ConvergenceError, ServoidError, ServoidWarning
from .._warn import warn
from ..data import Experiment, ExperimentSet, as_segments
from ..estimate import Estimate, fit_bj, fit_iv
from ._channels import output_name, single_name

__all__ = ["fit_direct_bj"]

#: A pole this far beyond the unit circle (|z| − 1) counts as unstable.
_UNSTABLE_MARGIN = 1e-3


def fit_direct_bj(
    data: Experiment | ExperimentSet,
    nb: int,
    nc: int,
    nd: int,
    nf: int,
    nk: int = 1,
    *,
    output: str | None = None,
    max_iter: int = 100,
    tol: float = 1e-9,
) -> Estimate:
    """Fit the plant by the direct approach (Box–Jenkins on u → y), loop-aware starts.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        Record(s) with the plant input u and the output y; a reference r,
        when recorded, gives the closed-loop IV start.
    nb, nc, nd, nf, nk : int
        Orders as in :func:`servoid.estimate.fit_bj`.
    output : str, optional
        Output channel name when there are several.
    max_iter, tol
        Passed to :func:`~servoid.estimate.fit_bj`.

    Returns
    -------
    Estimate
        Method ``"direct-bj"``; parameters ``b0…, f1…, c1…, d1…``;
        ``options["start"]`` names the start that reached the lower cost;
        ``options["consistent"]`` is False, with the reason in
        ``options["broken_assumptions"]``, for an unstable plant.

    Raises
    ------
    ConvergenceError
        Every start failed.
    """
    segments = as_segments(data)
    single_name(segments[0], "u", None, "plant input")
    y_name = output_name(segments[0], output)
    has_r = bool(segments[0].names_of("r"))
    start = None
    radius = None
    if has_r and nf > 0:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ServoidWarning)
                iv = fit_iv(data, nf, nb, nk, instrument="r", output=y_name)
            a = np.asarray(iv.parameters[:nf], dtype=float)
            radius = float(np.max(np.abs(np.roots(np.concatenate([[1.0], a])))))
            start = np.concatenate([iv.parameters[nf:], a, np.zeros(nc + nd)])
        except ServoidError:
            start = None
    fits: list[tuple[Estimate, str]] = []
    failure: ConvergenceError | None = None
    for init, label in ((None, "default (IV on u)"), (start, "closed-loop IV")):
        if label != "default (IV on u)" and init is None:
            continue
        try:
            with warnings.catch_warnings(record=True) as said:
                warnings.simplefilter("always", ServoidWarning)
                est = fit_bj(data, nb, nc, nd, nf, nk, output=y_name, init=init,
                             max_iter=max_iter, tol=tol)
            fits.append((est, label, said))  # type: ignore[arg-type]
        except ConvergenceError as exc:
            failure = failure or exc
    unstable = radius is not None and radius > 1.0 + _UNSTABLE_MARGIN
    if not fits:
        assert failure is not None
        if unstable:
            raise ConvergenceError(
                f"the direct Box–Jenkins search failed from every start ({failure}); the plant "
                f"is unstable (the closed-loop IV estimate has a pole at |z| = {radius:.3g}), so "
                "its predictor is unstable: use method = \"cliv\", or \"indirect\" with the "
                "known controller"
            ) from failure
        raise failure
    est, label, said = min(fits, key=lambda fit: float(fit[0].options["cost"]))  # type: ignore[misc]
    for w in said:
        warn(str(w.message), ServoidWarning)
    broken = []
    if unstable:
        broken.append(
            f"the plant is unstable (the closed-loop IV estimate has a pole at |z| = "
            f"{radius:.3g}), so the Box–Jenkins predictor, which simulates the plant, is "
            "unstable and its search can only return a stable, biased plant; use method = "
            "\"cliv\", or \"indirect\" with the known controller"
        )
        warn(f"the direct Box–Jenkins estimate is not consistent on this record: {broken[0]}",
             ServoidWarning)
    return dataclasses.replace(est, method="direct-bj", options={
        **est.options, "start": label, "starts": [fit[1] for fit in fits],
        "consistent": not broken, "broken_assumptions": broken,
    })
