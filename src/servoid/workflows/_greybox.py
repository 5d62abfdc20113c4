"""``method = "greybox"``: a user's ODE from the experiment file, fitted by simulation error.

The experiment file names a Python file and the functions in it::

    [identify]
    method = "greybox"
    model = "tanks.py:rhs"              # rhs(x, u, p) or rhs(t, x, u, p) -> dx/dt
    output_function = "tanks.py:level"  # optional: out(x, u, p) -> y; default the first state
    states = ["h1", "h2"]
    initial_state = [0.0, 0.0]          # default zeros
    estimate_initial = ["h1", "h2"]     # initial states to estimate (on each record)
    fixed = ["A"]                       # parameters held at their value
    log = ["k"]                         # positive parameters fitted as log θ
    substeps = 1                        # RK4 steps per sample
    multistart = 0                      # extra random starts
    covariance = "auto"                 # auto | white | robust | bootstrap

    [identify.parameters]               # name = start, or [start, lower, upper]; p's order
    k = [2e-5, 0.0, 1e-3]
    A = 0.0154

    [identify.units]                    # optional
    k = "m³/(s·V)"

    [identify.saturation]               # a state (clamp) or an input channel = [lower, upper]
    h1 = [0.0, 0.3]
    u = [0.0, 8.0]

The file is Python and running it runs whatever it holds, so it is executed
only when the command line has ``--allow-code`` (``allow_code=True`` in
:func:`servoid.workflows.identify`); otherwise the run stops with an
:class:`~servoid.OptionError` naming the file and the flag, before the file
is read.  The integrator, the fit and the replay on validation records are
:mod:`servoid.estimate._ode` and :mod:`servoid.estimate._ode_model`; the
format of the experiment file is documented in ``docs/greybox-ode.md``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from contextlib import nullcontext
from pathlib import Path
from typing import Any

import numpy as np

from .._checks import as_float, as_float_list, as_mapping, as_str, as_str_list, type_error
from .._errors import DataError, OptionError
from .._progress import stage
from .._warn import warn
from ..data import Experiment, ExperimentSpec
from ..estimate import GreyboxParameter
from ..estimate._diagnostics import MAX_STARTS
from ..estimate._ode import OdeSystem, make_system, simulation_seconds
from ..estimate._ode_model import fit_ode
from ..estimate._ode_user import executed_sha256, load_function, parse_ref
from ..report import Page
from ._arx import OUTPUT
from ._common import warnings_as_notes
from ._examples import greybox_tank
from ._lti import IdentificationResult, lti_result
from ._options import boolean, choice, integer, number, optional
from ._registry import Method, Option

__all__ = ["GREYBOX", "GreyboxResult"]

_WHERE = "[identify]"
#: iterations of a fit, few to many; each simulates the record n_free + 1 times (the residuals
#: and a finite-difference Jacobian). The tanks example (5 free parameters) took 11.
_ITERATIONS = (5, 20)
#: a bootstrap covariance refits 200 times (fit_greybox's n_bootstrap), each from the optimum
_BOOTSTRAP = (200 * 2, 200 * 5)


@dataclasses.dataclass(frozen=True, eq=False, repr=False)
class GreyboxResult(IdentificationResult):
    """A grey-box ODE identified from an experiment file, validated.

    The fields are those of
    :class:`~servoid.workflows.IdentificationResult`; the estimate's model
    is the fitted ODE (it replays itself on each validation record), and
    ``results.json`` describes it by its functions, states and values, with
    its model file (``model.model_file``) for ``load_results`` and
    ``servoid export``.
    """

    def to_dict(self) -> dict[str, Any]:
        """Everything in ``results.json``."""
        out = super().to_dict()
        out["model"] = self.estimate.model.to_dict()
        out["integrator_note"] = self.estimate.options.get("integrator_note", "")
        return out

    def page(self, files: Mapping[str, Path]) -> Page:
        """The report page, with the grey-box model described in words."""
        page = super().page(files)
        sections = tuple(
            dataclasses.replace(s, paragraphs=(_model_text(self),)) if s.title == "Model" else s
            for s in page.sections)
        return dataclasses.replace(page, sections=sections, subtitle=(
            f"{self.title}, parameters with their uncertainty, validated by free-run simulation "
            "on data not used for fitting"))


def run(spec: ExperimentSpec, options: Mapping[str, Any],
        truth: Mapping[str, float] | None) -> GreyboxResult:
    """Fit the user's ODE and validate it on each validation record."""
    model_key = f"{_WHERE} model"
    if options["model"] is None:
        raise OptionError(f"method = \"greybox\" needs {model_key} = \"<file>.py:<function>\", "
                          "the right-hand side dx/dt = rhs(x, u, p)")
    base = spec.source.parent if spec.source else spec.base_dir
    rhs_ref = parse_ref(options["model"], model_key)
    if not options.get("allow_code", False):
        where = (base / rhs_ref.file).resolve()
        raise OptionError(
            f"{model_key} = \"{options['model']}\" is Python code ({where}), and "
            "servoid runs a model file only when told to: check the file, then run "
            "servoid identify with --allow-code (allow_code=True in "
            "servoid.workflows.identify)")
    states, x0, estimate_initial = _states(options)
    params = _parameters(options)
    estimation, validations = spec.records()
    if not isinstance(estimation, Experiment):
        raise DataError("method = \"greybox\" fits one record: give one [data] file (several "
                        "records each start from their own state)")
    inputs = estimation.names_of("u")
    if not inputs:
        estimation.signal("u")  # raises, naming the channels there are
    output = options["output"] or estimation.names_of("y")[0]
    lower, upper, u_lower, u_upper = _saturations(options["saturation"], states, inputs)
    modules: dict[Path, Any] = {}
    pinned = options.get("code_sha256")  # a re-render: run only the bytes the run fitted
    rhs, path = load_function(rhs_ref, base, model_key, modules, pinned)
    measure: Any = 0
    out_source, out_hash, out_cache = "", "", ""
    if options["output_function"] is not None:
        out_key = f"{_WHERE} output_function"
        out_ref = parse_ref(options["output_function"], out_key)
        measure, out_path = load_function(out_ref, base, out_key, modules, pinned)
        out_source = f"{out_ref.file}:{out_ref.function}"
        out_hash = executed_sha256(modules[out_path])
        out_cache = f"{out_path}:{out_ref.function}"  # as a saved model's loader keys it
    theta0 = np.array([p.value for p in params])
    u = np.ascontiguousarray(estimation.signal("u"), dtype=float).reshape(
        estimation.n_samples, -1)
    system = make_system(rhs, measure, x0=x0, u=u, p=theta0, state_lower=lower,
                         state_upper=upper, input_lower=u_lower, input_upper=u_upper,
                         source=f"{rhs_ref.file}:{rhs_ref.function}", output_source=out_source,
                         path=path, compile=options["compile"],
                         cache_key=(str(path), executed_sha256(modules[path]), rhs_ref.function,
                                    out_cache, out_hash))
    if system.n_outputs != 1:
        raise OptionError(f"{_WHERE} output_function = \"{options['output_function']}\" returns "
                          f"{system.n_outputs} outputs; it must return the one measured output "
                          f"({output})")
    n_free = sum(not p.fixed for p in params) + len(estimate_initial)
    fitting: Any = nullcontext()
    if not system.compiled:  # before a fit that may take minutes: why, and how long
        fitting = stage(_python_integrator(system, x0, u, theta0, estimation.dt, options, n_free))
    notes = [system.note] if system.note else []
    if spec.preprocess.detrend != "none":
        notes.append(f"[preprocess] detrend = \"{spec.preprocess.detrend}\": the physical model "
                     "sees signals with their operating point removed; use \"none\" unless the "
                     "model is written in deviations")
    with fitting, warnings_as_notes() as fit_notes:  # lti_result warns each note again
        estimate = fit_ode(estimation, system, params, states=states, output=output, x0=x0,
                           estimate_initial=estimate_initial, substeps=options["substeps"],
                           covariance=options["covariance"], multistart=options["multistart"],
                           tol=options["tol"], max_nfev=options["max_nfev"],
                           rng=options["seed"])
    notes += fit_notes
    n_free = estimate.parameters.size
    title = (f"grey-box ODE {system.source} ({len(states)} states, {n_free} estimated "
             f"parameters{', compiled' if system.compiled else ''})")
    result = lti_result(spec, "greybox", estimate, title, validations, options, notes=notes,
                        truth=truth, records=estimation)
    return GreyboxResult(**{f.name: getattr(result, f.name)
                            for f in dataclasses.fields(IdentificationResult)})


def _python_integrator(system: OdeSystem, x0: Any, u: Any, theta0: Any, dt: float,
                       options: Mapping[str, Any], n_free: int) -> str:
    """Time a few steps of the Python integrator; warn of a fall-back; the fit's stage label.

    A model numba could not compile is announced now, with the reason and
    the time to expect, not in the notes at the end of a run that may last
    many minutes.
    """
    per = simulation_seconds(system, x0, u, theta0, dt, options["substeps"])
    starts = 1 + options["multistart"]
    lo, hi = ((n_free + 1) * i * starts for i in _ITERATIONS)
    if options["covariance"] == "bootstrap":
        lo, hi = lo + (n_free + 1) * _BOOTSTRAP[0], hi + (n_free + 1) * _BOOTSTRAP[1]
    expect = f"{_duration(lo * per)} to {_duration(hi * per)}"
    if options["compile"]:  # a fall-back, not the user's choice
        runs = f", {starts} starts" if starts > 1 else ""
        warn(f"{system.note}: one simulation of the {u.shape[0]} samples takes "
             f"{_duration(per)} and the fit needs some {lo}–{hi} of them ({n_free} free "
             f"parameters{runs}), so expect {expect}; a model numba compiles fits about 100 "
             "times faster (docs/greybox-ode.md says what compiles)")
    return f"fitting with the Python integrator (expect {expect})"


def _duration(seconds: float) -> str:
    if seconds < 1.0:
        return f"{seconds:.2g} s"
    if seconds < 90.0:
        return f"{seconds:.0f} s"
    if seconds < 5400.0:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


# -- option checks ----------------------------------------------------------------------------


def _ref(value: Any, where: str, name: str) -> str:
    text = as_str(name, value, where=where)
    parse_ref(text, f"{where} {name}")
    return text


def _names(value: Any, where: str, name: str) -> list[str]:
    names = as_str_list(name, value, where=where)
    if len(set(names)) != len(names):
        raise OptionError(f"{where} {name} lists a name twice: {names}")
    return names


def _numbers(value: Any, where: str, name: str) -> list[float]:
    return as_float_list(name, value, min_length=1, where=where)


def _table(value: Any, where: str, name: str) -> dict[str, Any]:
    return dict(as_mapping(name, value, where=where))


def _parameters(options: Mapping[str, Any]) -> list[GreyboxParameter]:
    """``[identify.parameters]``, ``fixed``, ``log`` and units as parameters."""
    where = f"{_WHERE[:-1]}.parameters]"
    table = options["parameters"]
    if not table:
        raise OptionError(f"method = \"greybox\" needs {where}: one line per parameter, "
                          "name = start value or name = [start, lower, upper], in the order "
                          "the model reads p")
    fixed = options["fixed"]
    units = options["units"] or {}
    for key, listed in (("fixed", fixed), ("units", list(units)), ("log", options["log"])):
        unknown = [n for n in listed if n not in table]
        if unknown:
            raise OptionError(f"{_WHERE} {key} names {', '.join(map(repr, unknown))}, not in "
                              f"{where}; the parameters are {', '.join(table)}")
    out = []
    for name, value in table.items():
        if isinstance(value, (list, tuple)):
            if len(value) != 3:
                raise OptionError(f"{where} {name} = {list(value)}: give the start value, or "
                                  "[start, lower, upper]")
            start = as_float(name, value[0], where=where)
            lo, hi = (as_float(name, v, finite=False, where=where) for v in value[1:])
            if np.isnan(lo) or np.isnan(hi) or not lo < hi:
                raise OptionError(f"{where} {name}: lower = {lo:g} must be below upper = {hi:g}")
            if not lo <= start <= hi:
                raise OptionError(f"{where} {name}: the start value {start:g} lies outside "
                                  f"[{lo:g}, {hi:g}]")
        elif isinstance(value, bool) or not isinstance(value, (int, float)):
            raise type_error(name, value, "a number or [start, lower, upper]", where=where)
        else:
            start, lo, hi = as_float(name, value, where=where), -np.inf, np.inf
        unit = as_str(name, units.get(name, ""), empty=True, where=f"{_WHERE[:-1]}.units]")
        log = name in options["log"]
        if log and not (start > 0 and lo >= 0):
            raise OptionError(f"{_WHERE} log names {name!r}: fitted as log {name}, it needs a "
                              f"start > 0 and a lower bound >= 0, got start {start:g}, lower "
                              f"{lo:g}")
        out.append(GreyboxParameter(name, start, lo, hi, unit, fixed=name in fixed,
                                    transform="log" if log else "none"))
    if all(p.fixed for p in out) and not options["estimate_initial"]:
        raise OptionError(f"{_WHERE} fixed holds every parameter and estimate_initial is empty: "
                          "nothing to estimate")
    return out


def _states(options: Mapping[str, Any]) -> tuple[tuple[str, ...], np.ndarray, list[str]]:
    states = options["states"]
    if not states:
        raise OptionError(f"method = \"greybox\" needs {_WHERE} states = [\"x\", ...]: a name "
                          "per state, in the order rhs reads x")
    x0 = options["initial_state"]
    if x0 is None:
        x0 = [0.0] * len(states)
    if len(x0) != len(states):
        raise OptionError(f"{_WHERE} initial_state has {len(x0)} values and states names "
                          f"{len(states)} ({', '.join(states)}); give one value per state")
    chosen = options["estimate_initial"]
    unknown = [n for n in chosen if n not in states]
    if unknown:
        raise OptionError(f"{_WHERE} estimate_initial names {', '.join(map(repr, unknown))}, "
                          f"which is not a state; the states are {', '.join(states)}")
    return tuple(states), np.array(x0, dtype=float), list(chosen)


def _saturations(table: Mapping[str, Any] | None, states: tuple[str, ...],
                 inputs: tuple[str, ...]) -> tuple[np.ndarray, ...]:
    where = f"{_WHERE[:-1]}.saturation]"
    lower, upper = np.full(len(states), -np.inf), np.full(len(states), np.inf)
    u_lower, u_upper = np.full(len(inputs), -np.inf), np.full(len(inputs), np.inf)
    for name, value in dict(table or {}).items():
        if name in states:
            k, lo_arr, hi_arr = states.index(name), lower, upper
        elif name in inputs:
            k, lo_arr, hi_arr = inputs.index(name), u_lower, u_upper
        else:
            raise OptionError(f"{where} {name}: not a state or an input channel; the states are "
                              f"{', '.join(states)} and the inputs {', '.join(inputs)}")
        lo, hi = as_float_list(name, value, length=2, finite=False, where=where)
        if np.isnan(lo) or np.isnan(hi) or not lo < hi:
            raise OptionError(f"{where} {name} = [{lo:g}, {hi:g}]: lower must be below upper")
        lo_arr[k], hi_arr[k] = lo, hi
    return lower, upper, u_lower, u_upper


def _model_text(result: GreyboxResult) -> str:
    est = result.estimate
    o = est.options
    ident = o.get("identifiability") or {}
    flagged = ident.get("flags") if isinstance(ident, Mapping) else None
    parts = [
        (f"{result.title}, fitted by simulation error (bounded trust-region least squares over "
        f"the free parameters{' and initial states' if est.model.estimated else ''}) on "
        f"{est.n_samples} samples; fixed-step RK4 with {o.get('substeps', 1)} step(s) per "
        "sample, the input held between samples; residual variance "
        f"{est.noise_variance:.4g}."),
        f"Covariance: {o.get('covariance')} (from the solver's Jacobian).",
        "Integrator: compiled with numba." if o.get("compiled") else
        f"Integrator: Python ({o.get('integrator_note') or 'not compiled'}).",
    ]
    if flagged:
        parts.append("Identifiability checks flagged: see the notes.")
    return " ".join(parts)


GREYBOX = Method(
    name="greybox",
    summary="a grey-box ODE written in Python (model = \"file.py:rhs\"), its parameters and "
            "initial states fitted by simulation error with bounds, saturations, multistart "
            "and identifiability checks; needs --allow-code",
    options=(
        OUTPUT,
        Option("model", None, optional(_ref),
               "required: right-hand side \"file.py:function\", rhs(x, u, p) or rhs(t, x, u, "
               "p) -> dx/dt; the file is run only with --allow-code"),
        Option("output_function", None, optional(_ref),
               "output \"file.py:function\", out(x, u, p) -> y; none: the first state"),
        Option("states", None, optional(_names), "required: a name per state, in the order of x"),
        Option("initial_state", None, optional(_numbers),
               "initial state, one value per state; none: zeros"),
        Option("estimate_initial", [], _names,
               "states whose initial value is estimated (again on each validation record)"),
        Option("parameters", None, optional(_table),
               "required, [identify.parameters]: name = start or [start, lower, upper], in p's "
               "order"),
        Option("fixed", [], _names, "parameters held at their start value"),
        Option("log", [], _names,
               "positive parameters fitted as log θ (relative steps, log-uniform random starts)"),
        Option("units", None, optional(_table), "[identify.units]: name = \"unit\""),
        Option("saturation", None, optional(_table),
               "[identify.saturation]: a state (clamp) or an input channel = [lower, upper]"),
        Option("substeps", 1, integer(minimum=1), "RK4 steps per sample period"),
        Option("multistart", 0, integer(minimum=0, maximum=MAX_STARTS),
               "extra random starts within the bounds; the best wins"),
        Option("seed", 0, integer(minimum=0), "seed of the random starts and resamples"),
        Option("covariance", "auto", choice(("auto", "white", "robust", "bootstrap")),
               "parameter covariance (auto: robust, allowing coloured residuals)"),
        Option("tol", 1e-10, number(positive=True), "relative tolerance of the solver"),
        Option("max_nfev", None, optional(integer(minimum=1)),
               "most solver evaluations per start; none: 100·(free parameters + 1)"),
        Option("compile", True, boolean(),
               "compile the model with numba when it can (false: plain Python, for debugging)"),
    ),
    run=run,
    tables=("validation",),
    runs_code=True,
    example=greybox_tank,
)
