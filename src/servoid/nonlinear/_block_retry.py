"""Other starts before a block-oriented structure is called wrong.

A joint output-error search of a block model is local: from the default
start (:func:`~servoid.nonlinear.fit_block`'s, read from the data) it can
stall with an unstable linear block, or end where the fit explains no more
than chance, although the structure is right.  :func:`fit_block_retrying`
tries, in this order, before it gives up:

1. the default start;
2. for a non-monotone shape named by its kind (``"abs"``), the centre at 0
   (the sign of the linear block is settled by the fit itself);
3. for a discrete linear block, a continuous one of the same order
   (``linear = "tf"``, ``n_poles = nf``, ``n_zeros = nb − 1``): a smoother
   search whose zero-order-hold model is the same family;
4. ``multistart = N`` random starts (seeded by ``seed``): each static shape
   named by its kind starts from breakpoints at random quantiles of its
   input (the record's input before the linear block; its output, the
   scale a unit-slope shape after the block sees, after it), or from
   randomly perturbed parameters for the other shapes.

It stops at the first start whose linear block is stable; otherwise it
keeps the fit of lowest cost.  When none fits, the message says which case
it is: *the structure cannot explain the data* (every start ended in the
"no more than chance" refusal), or *no start found a fit* (with each
start's reason).
"""

from __future__ import annotations

import dataclasses
import warnings
from typing import Any

import numpy as np

from .._checks import as_int
from .._errors import ConvergenceError, IdentifiabilityError, ServoidError, ServoidWarning
from .._warn import warn
from ..data import as_segments
from ..estimate import Estimate
from ._block_fit import fit_block

__all__ = ["CHANCE", "fit_block_retrying"]

#: The start of the refusal of a fit that explains no more than chance.
CHANCE = "the fitted model explains no more of the output than chance"
#: Refusals another start may cure (the others are about the data or the options).
_CURABLE = (CHANCE, "the linear block integrates", "the block-model search failed",
            "the data cannot separate")


def _starts(structure: str, kw: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    from ._static import AbsoluteValue

    out: list[tuple[str, dict[str, Any]]] = [("the default start", {})]
    for side in ("input_nonlinearity", "output_nonlinearity"):
        if kw.get(side) == "abs":
            out.append(("the centre of |x| at 0", {side: AbsoluteValue(0.0)}))
    if kw.get("linear", "oe") == "oe":
        nb = kw.get("nb") or 2
        nf = kw.get("nf")
        nf = 2 if nf is None else nf
        if nf >= 1:
            out.append((f"a continuous linear block ({nf} poles)",
                        {"linear": "tf", "nb": None, "nf": None, "nk": None,
                         "n_poles": nf, "n_zeros": max(min(nb - 1, nf - 1), 0)}))
    return out


def _random_starts(data: Any, kw: dict[str, Any], n: int,
                   seed: int) -> list[tuple[str, dict[str, Any]]]:
    """``n`` random starts of the shapes named by their kind (none when no shape is named)."""
    from ._static import AbsoluteValue, DeadZone, Saturation, SignedPower, from_data

    if n == 0:
        return []
    seg = as_segments(data)[0]
    u = np.asarray(seg.signal(kw.get("input", "u")), dtype=float)[:, 0]
    out_name = kw.get("output") or seg.names_of("y")[0]
    y = np.asarray(seg[out_name], dtype=float).ravel()
    rng = np.random.default_rng(seed)
    sides = [(side, x) for side, x in (("input_nonlinearity", u), ("output_nonlinearity", y))
             if isinstance(kw.get(side), str)]
    out: list[tuple[str, dict[str, Any]]] = []
    for k in range(n):
        change: dict[str, Any] = {}
        for side, x in sides:
            x = x[np.isfinite(x)]
            kind = kw[side]
            if kind == "deadzone":
                lo, hi = np.sort(rng.uniform(0.05, 0.95, 2))
                change[side] = DeadZone(*(float(q) for q in np.quantile(x, [lo, hi])))
            elif kind == "saturation":
                lo, hi = rng.uniform(0.0, 0.3), rng.uniform(0.7, 1.0)
                change[side] = Saturation(*(float(q) for q in np.quantile(x, [lo, hi])))
            elif kind == "abs":
                change[side] = AbsoluteValue(float(np.quantile(x, rng.uniform(0.1, 0.9))))
            elif kind == "power":
                change[side] = SignedPower(float(rng.uniform(0.5, 2.0)))
            else:  # polynomial, piecewise-linear: the data's start, perturbed
                shape = from_data(kind, x, degree=kw.get("degree") or 3,
                                  breakpoints=kw.get("breakpoints"))
                theta = np.asarray(shape.parameters, dtype=float)
                try:
                    change[side] = shape.with_parameters(
                        theta + rng.normal(0.0, 0.3, theta.size) * (np.abs(theta) + 0.1))
                except ServoidError:
                    change[side] = shape
        if change:
            out.append((f"random start {k + 1}", change))
    return out


def _stable(est: Estimate) -> bool:
    lin = est.model.linear
    den = np.asarray(lin.f[0] if hasattr(lin, "f") else lin.den, dtype=float)
    roots = np.roots(den) if den.size > 1 else np.zeros(0)
    if getattr(lin, "dt", None) is None:  # continuous
        return bool(np.all(roots.real < 0))
    return bool(np.all(np.abs(roots) < 1.0))


def fit_block_retrying(data: Any, structure: str, multistart: int = 0, seed: int = 0,
                       **kw: Any) -> Estimate:
    """:func:`~servoid.nonlinear.fit_block`, from other starts before it gives up.

    Parameters are those of :func:`~servoid.nonlinear.fit_block`, and:

    multistart : int
        Random starts tried after the others when none gave a stable
        linear block (0: none; the shapes named by their kind only).
    seed : int
        Seed of the random starts (the same seed, the same starts).

    The estimate's ``options`` gain ``start`` (the start kept) and
    ``starts`` (each start tried and how it ended).

    Raises
    ------
    IdentifiabilityError
        "the structure cannot explain the data" (every start's fit explains
        no more of the output than chance), or "no start found a fit" (the
        reasons of each).
    """
    tried: list[tuple[str, str]] = []
    fits: list[tuple[str, Estimate, bool]] = []
    first_error: Exception | None = None
    multistart = as_int("multistart", multistart, minimum=0, maximum=1000)
    seed = as_int("seed", seed, minimum=0)
    for name, change in _starts(structure, kw) + _random_starts(data, kw, multistart, seed):
        try:
            with warnings.catch_warnings(record=True) as said:
                warnings.simplefilter("always")
                est = fit_block(data, structure, **{**kw, **change})
        except (IdentifiabilityError, ConvergenceError) as exc:
            if not str(exc).startswith(_CURABLE):
                raise  # about the data or the options: no start changes it
            first_error = first_error or exc
            tried.append((name, str(exc)))
            continue
        stable = _stable(est)
        tried.append((name, "stable linear block" if stable else "unstable linear block"))
        fits.append((name, est, stable))
        if stable:
            if name == "the default start":
                for w in said:  # the default fit's own warnings, as fit_block gives them
                    warn(str(w.message), w.category)
            break
    starts = [{"start": n, "outcome": o} for n, o in tried]
    if not fits:
        if all(o.startswith(CHANCE) for _, o in tried):
            raise IdentifiabilityError(
                f"the structure cannot explain the data: from {_names(tried)} {CHANCE} — the "
                "input may never leave a dead zone, or the shape or the delay nk is wrong")
        raise IdentifiabilityError(
            "no start found a fit: " + "; ".join(f"{n}: {o}" for n, o in tried)
            + ("" if multistart else "; more starts: multistart = 10")) from first_error
    name, est, stable = min(fits, key=lambda f: (not f[2], float(f[1].options.get("cost",
                                                                                  np.inf))))
    if len(tried) > 1:
        how = (f"the fit from {name} is kept" if stable else
               "no start found a stable linear block; the fit of lowest cost, from "
               f"{name}, is kept")
        warn(f"the {structure} fit tried other starts ({_outcomes(tried)}): {how}",
             ServoidWarning)
    return dataclasses.replace(est, options={**est.options, "start": name, "starts": starts})


def _names(tried: list[tuple[str, str]]) -> str:
    names = [n for n, _ in tried if not n.startswith("random start")]
    randoms = len(tried) - len(names)
    if randoms:
        names.append(f"{randoms} random start{'s' if randoms > 1 else ''}")
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def _outcomes(tried: list[tuple[str, str]]) -> str:
    return "; ".join(f"{n}: {o.split(':')[0] if len(o) > 80 else o}" for n, o in tried)
