"""``method = "two-stage" | "cliv" | "indirect"``: a plant from closed-loop records, any loop."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from functools import partial
from typing import Any

import numpy as np

from .._checks import as_bool, as_float, as_float_list
from .._errors import DataError, ServoidError
from ..closedloop import fit_cliv, fit_indirect_tf, fit_two_stage
from ..data import Experiment, ExperimentSet, ExperimentSpec
from ..estimate import Estimate, fit_arx
from ..models import PolynomialModel, TransferFunction, c2d
from ._examples import closed_loop
from ._lti import IdentificationResult, lti_result
from ._options import HORIZON, boolean, choice, integer, optional, text
from ._pem import COVARIANCE, SEARCH, orders_text
from ._registry import Method, Option, TableSchema

__all__ = ["CLIV", "INDIRECT", "LOOP", "TWO_STAGE", "controller_from_loop", "known_loop"]

_OUTPUT = Option("output", None, optional(text()), "output channel when the data have several")


def _run_two_stage(spec: ExperimentSpec, options: Mapping[str, Any],
                   truth: Mapping[str, float] | None) -> IdentificationResult:
    estimation, validations = spec.records()
    est = fit_two_stage(estimation, options["nb"], options["nf"], options["nk"],
                        stage1_order=options["stage1_order"], projection=options["projection"],
                        structure=options["structure"], nc=options["nc"], nd=options["nd"],
                        output=options["output"], multistart=options["multistart"],
                        rng=options["seed"], max_iter=options["max_iter"], tol=options["tol"])
    est = _plant_input(est, estimation)
    how = "projection" if options["projection"] else "two-stage"
    title = f"{options['structure'].upper()} plant by the {how} method " \
            f"({orders_text(est.options, ('nb', 'nf', 'nk'))})"
    note = (f"stage 1: a FIR of order {est.options['stage1_order']} from the reference explains "
            f"{100 * est.options['reference_explains']:.0f} % of the input's variance")
    loop = in_loop(est, estimation, options["[loop]"])
    est = _mark(est, loop)
    return lti_result(spec, "two-stage", est, title, validations, options, truth=truth,
                      notes=[note, *broken(est), *loop[1]], closed_loop=True, records=estimation,
                      how="the two-stage method (FIR r → u, then prediction error)",
                      loop_model=loop[0])


def _run_cliv(spec: ExperimentSpec, options: Mapping[str, Any],
              truth: Mapping[str, float] | None) -> IdentificationResult:
    estimation, validations = spec.records()
    est = fit_cliv(estimation, options["na"], options["nb"], options["nk"],
                   output=options["output"], iterations=options["iterations"],
                   covariance=options["covariance"])
    est = _plant_input(est, estimation)
    title = f"plant by closed-loop IV ({orders_text(est.options, ('na', 'nb', 'nk'))})"
    loop = in_loop(est, estimation, options["[loop]"])
    est = _mark(est, loop)
    return lti_result(spec, "cliv", est, title, validations, options, truth=truth,
                      notes=[est.options["instrument_choice"], *broken(est), *loop[1]],
                      closed_loop=True, records=estimation,
                      how="closed-loop instrumental variables (the reference as instrument)",
                      loop_model=loop[0])


def _run_indirect(spec: ExperimentSpec, options: Mapping[str, Any],
                  truth: Mapping[str, float] | None) -> IdentificationResult:
    estimation, validations = spec.records()
    dt = estimation.dt
    controller, feedback = known_loop(options["[loop]"], dt)
    est = fit_indirect_tf(estimation, controller, options["nb"], options["nf"], options["nk"],
                          feedback=feedback, structure=options["structure"],
                          refine=options["refine"], output=options["output"],
                          multistart=options["multistart"], rng=options["seed"],
                          max_iter=options["max_iter"], tol=options["tol"])
    est = _plant_input(est, estimation)
    title = f"plant by the indirect approach ({orders_text(est.options, ('nb', 'nf', 'nk'))})"
    loop = in_loop(est, estimation, options["[loop]"])
    est = _mark(est, loop)
    return lti_result(spec, "indirect", est, title, validations, options, truth=truth,
                      notes=loop[1], closed_loop=True, records=estimation,
                      how="the indirect approach (closed loop r → y with the known controller)",
                      loop_model=loop[0])


def broken(est: Estimate) -> list[str]:
    """The estimate's own words on the assumptions this record breaks, as notes."""
    return [f"not consistent on this record: {why}"
            for why in est.options.get("broken_assumptions", [])]


#: A plant pole at |z| >= 1 − this is unstable or an integrator: it is validated in its loop.
_MARGINAL = 1e-6


def in_loop(est: Estimate, data: Experiment | ExperimentSet, loop: Mapping[str, Any]
            ) -> tuple[PolynomialModel | None, list[str]]:
    """The closed loop r → y to validate an unstable (or integrating) plant in, with a note.

    A plant with a pole on or outside the unit circle cannot be run free:
    its simulation grows without bound, and so would its "fit".  It is
    validated in its loop instead, ``u = C·(r − F·y)``, with the controller
    of ``[loop]`` when it is known and otherwise with the controller
    identified from the record (least squares of u on r − y, which the
    controller maps without noise).  Returns (None, []) for a stable plant.
    """
    model = est.model
    if not isinstance(model, PolynomialModel) or model.n_inputs != 1:
        return None, []
    bg = np.concatenate([np.zeros(model.nk[0]), model.b[0]])
    fg = np.convolve(model.a, model.f[0]) if model.f is not None else np.asarray(model.a)
    radius = float(np.max(np.abs(np.roots(fg)))) if fg.size > 1 else 0.0
    if radius < 1.0 - _MARGINAL:
        return None, []
    kind = "unstable" if radius > 1.0 + _MARGINAL else "an integrator (a pole on the unit circle)"
    first = data if isinstance(data, Experiment) else data[0]
    what = f"the identified plant is {kind}" + (
        f" (a pole at |z| = {radius:.4g})" if radius > 1.0 + _MARGINAL else "")
    if len(first.names_of("r")) != 1:
        return None, [f"{what}: its free run below grows without bound; record the reference r "
                      "(role 'r') to validate it in its loop"]
    if loop.get("controller") is not None:
        c, f = known_loop(loop, first.dt)
        if isinstance(c, TransferFunction) and c.dt is None:
            c = c2d(c, first.dt, "tustin")
        cn, cd = _q(c)
        fn, fd = _q(f)
        how = "the known controller of [loop]"
    else:
        fn, fd = np.ones(1), np.ones(1)
        try:
            cn, cd, how = _identified_controller(data)
        except ServoidError as exc:
            return None, [f"{what}: a free run of it diverges, and it could not be validated in "
                          f"its loop ({exc}); add the controller as [loop] controller"]
    bcl = np.convolve(np.convolve(bg, cn), fd)
    fcl = _padd(np.convolve(np.convolve(fg, cd), fd), np.convolve(np.convolve(bg, cn), fn))
    bcl, fcl = bcl / fcl[0], fcl / fcl[0]
    lead = int(np.flatnonzero(np.abs(bcl) > 0)[0]) if np.any(bcl) else 0
    r_name = first.names_of("r")[0]
    y_name = model.output_name
    closed = PolynomialModel([1.0], (bcl[lead:],), (lead,), first.dt, f=(fcl,),
                             input_names=(r_name,), output_name=y_name)
    loop_radius = float(np.max(np.abs(np.roots(fcl)))) if fcl.size > 1 else 0.0
    note = (f"{what}: it is validated in its loop, r → y with {how}, not run free; the fits "
            f"and residual tests below are of that closed loop")
    if loop_radius >= 1.0:
        note += (f". With this controller the identified loop itself is unstable (a pole at "
                 f"|z| = {loop_radius:.4g}): the plant estimate does not describe the loop "
                 "that ran, so its validation fails")
    return closed, [note]


def _mark(est: Estimate, loop: tuple[PolynomialModel | None, list[str]]) -> Estimate:
    """The estimate, marked as validated in its loop when it is."""
    if loop[0] is None:
        return est
    return dataclasses.replace(est, options={**est.options, "validated_in_loop": True})


def _identified_controller(data: Experiment | ExperimentSet
                           ) -> tuple[np.ndarray, np.ndarray, str]:
    """The controller u = C·(r − y), fitted by ARX on the record (it is noise-free)."""
    segments = [data] if isinstance(data, Experiment) else list(data)
    pieces = []
    for seg in segments:
        r = np.asarray(seg[seg.names_of("r")[0]], dtype=float)
        y = np.asarray(seg[seg.names_of("y")[0]], dtype=float)
        u = np.asarray(seg[seg.names_of("u")[0]], dtype=float)
        pieces.append(Experiment.from_arrays(seg.dt, u=r - y, y=u))
    exp: Experiment | ExperimentSet = pieces[0] if len(pieces) == 1 else ExperimentSet(
        tuple(pieces))
    best = None
    for na in range(4):
        est = fit_arx(exp, na, na + 1, 0)
        rms = float(np.sqrt(np.mean(est.residuals**2)))
        scale = float(np.std(np.concatenate([np.asarray(p["y"]) for p in pieces])))
        best = (est, na)
        if rms <= 1e-3 * max(scale, 1e-300):
            break
    assert best is not None
    est, na = best
    a = np.concatenate([[1.0], est.parameters[:na]])
    b = np.asarray(est.parameters[na:], dtype=float)
    return b, a, f"the controller identified from the record (ARX({na}, {na + 1}) of u on r − y)"


def _q(value: TransferFunction | float) -> tuple[np.ndarray, np.ndarray]:
    """Numerator and monic denominator in q⁻¹ of a discrete TF or a gain."""
    if isinstance(value, TransferFunction):
        den = np.asarray(value.den, dtype=float)
        num = np.concatenate([np.zeros(den.size - np.asarray(value.num).size), value.num])
        return num / den[0], den / den[0]
    return np.array([float(value)]), np.ones(1)


def _padd(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    out = np.zeros(max(p.size, q.size))
    out[: p.size] += p
    out[: q.size] += q
    return out


def _plant_input(est: Estimate, data: Experiment | ExperimentSet) -> Estimate:
    """The estimate's options with the plant input named like the other methods'."""
    first = data if isinstance(data, Experiment) else data[0]
    names = first.names_of("u")
    if len(names) != 1:
        raise DataError(f"the closed-loop methods need one plant input u; the data have "
                        f"{len(names)} ({', '.join(names) or 'none'})")
    return dataclasses.replace(est, options={**est.options, "input": "u", "inputs": [names[0]]})


def controller_from_loop(table: Mapping[str, Any], dt: float
                         ) -> tuple[TransferFunction | float, TransferFunction | float]:
    """The known controller and feedback of ``[loop]`` (discrete at ``dt``)."""
    return known_loop(LOOP.parse(table, "indirect"), dt)


def known_loop(loop: Mapping[str, Any], dt: float
               ) -> tuple[TransferFunction | float, TransferFunction | float]:
    """The controller and feedback of a checked ``[loop]`` (:data:`LOOP`), discrete at ``dt``."""
    if loop["controller"] is None:
        raise DataError("method = \"indirect\" needs the controller: add [loop] controller = "
                        "{num = [...], den = [...]} (discrete in q, at the data's dt) or a gain")
    return _discrete(loop["controller"], dt), _discrete(loop["feedback"], dt)


def _transfer(value: Any, where: str, key: str) -> float | dict[str, Any]:
    """A gain, or ``{num, den[, dt]}`` of a discrete transfer function, checked."""
    if isinstance(value, Mapping):
        extra = sorted(set(value) - {"num", "den", "dt", "continuous"})
        if extra or "num" not in value or "den" not in value:
            raise DataError(f"{where} {key} must be a gain or {{num = [...], den = [...]}} "
                            f"(descending powers of z, at the data's dt; or of s with "
                            f"continuous = true); got keys {sorted(value)}")
        num = as_float_list(f"{key}.num", value["num"], min_length=1, where=where)
        den = as_float_list(f"{key}.den", value["den"], min_length=1, where=where)
        continuous = as_bool(f"{key}.continuous", value.get("continuous", False))
        if continuous and "dt" in value:
            raise DataError(f"{where} {key} has both dt and continuous = true: a continuous "
                            "transfer function has no dt; drop one of them")
        at = None if "dt" not in value else as_float(f"{key}.dt", value["dt"], positive=True,
                                                     unit="s", where=where)
        return {"num": num, "den": den, "dt": at, "continuous": continuous}
    return as_float(key, value, where=where)


def _discrete(value: float | Mapping[str, Any], dt: float) -> TransferFunction | float:
    """The transfer function of ``[loop]``: discrete at dt, or continuous when it says so."""
    if isinstance(value, Mapping):
        if value.get("continuous"):
            return TransferFunction(value["num"], value["den"])
        return TransferFunction(value["num"], value["den"],
                                dt=dt if value["dt"] is None else value["dt"])
    return value


#: ``[loop]`` of the methods that know the controller: u = C(q)·(r − F(q)·y).
LOOP = TableSchema("loop", (
    Option("controller", None, optional(_transfer),
           "the controller C(q) from r − F·y to u: a gain or {num = [...], den = [...]} in "
           "descending powers of z, at the data's dt (or dt = …), or in powers of s with "
           "continuous = true when only the continuous design is known (discretised by "
           "Tustin; the indirect approach then checks that the guess does not move the "
           "plant); required by the indirect approach, and the loop an unstable identified "
           "plant is validated in"),
    Option("feedback", 1.0, _transfer, "the feedback F(q) from y: a gain or {num, den}"),
), help="the known loop")


TWO_STAGE = Method(
    name="two-stage",
    summary="plant from a closed-loop record with an unknown controller: a FIR r → u gives the "
            "noise-free input, then OE (or BJ) from it to y",
    options=(
        _OUTPUT,
        Option("nb", 2, integer(minimum=1), "B coefficients of the plant"),
        Option("nf", 2, integer(minimum=0), "order of F (plant poles)"),
        Option("nk", 1, integer(minimum=0), "plant delay [samples]"),
        Option("stage1_order", None, optional(integer(minimum=1)),
               "FIR length of stage 1 (default: by AIC)"),
        Option("projection", False, boolean(), "two-sided FIR (the projection method)"),
        Option("structure", "oe", choice(("oe", "bj")), "stage-2 structure"),
        Option("nc", 1, integer(minimum=0), "BJ noise zeros (structure = \"bj\")"),
        Option("nd", 1, integer(minimum=0), "BJ noise poles (structure = \"bj\")"),
        *SEARCH,
        HORIZON,
    ),
    run=_run_two_stage,
    tables=(LOOP, "validation"),
    example=partial(closed_loop, identify={"method": "two-stage"}),
)

CLIV = Method(
    name="cliv",
    summary="plant from a closed-loop record with an unknown controller by instrumental "
            "variables built from the reference",
    options=(
        _OUTPUT,
        Option("na", 2, integer(minimum=0), "number of poles"),
        Option("nb", 2, integer(minimum=1), "B coefficients"),
        Option("nk", 1, integer(minimum=0), "delay [samples]"),
        Option("iterations", 2, integer(minimum=1), "refined-IV passes"),
        COVARIANCE,
        HORIZON,
    ),
    run=_run_cliv,
    tables=(LOOP, "validation"),
    example=partial(closed_loop, identify={"method": "cliv"}),
)

INDIRECT = Method(
    name="indirect",
    summary="plant of any order from a closed-loop record and the known controller "
            "([loop] controller, feedback): OE of r → y, then the plant",
    options=(
        _OUTPUT,
        Option("nb", 2, integer(minimum=1), "B coefficients of the plant"),
        Option("nf", 2, integer(minimum=0), "order of F (plant poles)"),
        Option("nk", 1, integer(minimum=0), "plant delay [samples]"),
        Option("structure", "oe", choice(("oe", "arx")), "closed-loop fit of r → y"),
        Option("refine", True, boolean(), "refine by output error with the plant as parameters"),
        *SEARCH,
        HORIZON,
    ),
    run=_run_indirect,
    tables=(LOOP, "validation"),
    example=partial(closed_loop, identify={"method": "indirect"},
                    loop={"controller": {"num": [0.56, -0.5], "den": [1.0, -1.0]}}),
)
