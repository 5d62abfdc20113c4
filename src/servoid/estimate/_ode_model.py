"""A user's grey-box ODE fitted by simulation error, and replayed on new records.

:func:`fit_ode` fits the free parameters and the chosen initial states of
an :class:`~servoid.estimate._ode.OdeSystem` to one record with
:func:`~servoid.estimate.fit_greybox` (bounded least squares on the
simulation error, multistart, covariance options and the identifiability
checks), passing it the system's own simulator.  Initial states to
estimate are extra parameters named ``"<state>(0)"``, bounded by the
state's clamp.

The result's model is an :class:`OdeModel`: frozen, it holds the system,
every parameter value and ``dt``, and implements
:class:`servoid.validate.Replayable` — ``replay(y, u)`` simulates a new
record from its input, with the initial states that were estimated refitted
to that record (a small bounded least squares over those states only; the
parameters stay fixed), so :func:`servoid.validate.validate` and the
workflows' ``[validation] file`` treat it as any other model.

It also travels: :meth:`OdeModel.to_record` writes it into a servoid model
file as a *reference* to the user's code (the file's absolute path, its
SHA-256 and the function names) with every number, never the code; and
:meth:`OdeModel.from_record` runs that file again only when the caller
consents (``allow_code=True``) and the file's SHA-256 is still the one
recorded, so the model read back replays bit for bit as the one fitted.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from .._checks import as_array, as_float, type_error
from .._errors import (
    ChannelError,
    DataError,
    FileFormatError,
    ModelError,
    OptionError,
    ServoidWarning,
    check_option,
)
from .._lazy import optimize
from .._warn import warn
from ..data import Experiment
from ._estimate import Estimate
from ._greybox import GreyboxParameter, fit_greybox
from ._ode import OdeSystem, make_system
from ._ode_user import code_ref, load_recorded

__all__ = ["OdeModel", "fit_ode", "initial_name"]

#: residual of a diverged replay trial: finite, so the solver rejects the step
_PENALTY = 1e50
_INITIALS = ("auto", "estimate", "zero", "measured")
_SIGNATURES = ("rhs(x, u, p)", "rhs(t, x, u, p)")
#: samples of input the loader probes the user's functions with (as make_system does)
_PROBE = 8


@dataclass(frozen=True, eq=False)
class OdeModel:
    """A fitted grey-box ODE: the system, its parameters and ``dt``.

    Attributes
    ----------
    system : OdeSystem
        The user's functions with their integrator.
    names : tuple of str
        Every model parameter (free and fixed), in the order ``p`` holds them.
    theta : ndarray
        Their values.
    states : tuple of str
        State names.
    x0 : ndarray
        Initial state of the estimation record (estimated entries fitted).
    estimated : tuple of int
        States whose initial value is refitted on each record by ``replay``.
    dt : float
        Sample period [s].
    substeps : int
        RK4 steps per sample.
    inputs : tuple of str
        Input channel names, one per column of ``u`` (empty: unnamed).
    output : str
        The measured output's name ('' : unnamed).
    units : tuple of str
        Unit of each parameter of ``names`` (empty: none given).
    fixed : tuple of bool
        Which parameters were held at their value (empty: none).
    covariance : ndarray or None
        Covariance of the estimated parameters (``covariance_names``).
    covariance_names : tuple of str
        The estimated parameters, ``"<state>(0)"`` for an initial state.
    """

    #: the model calls the user's Python code: a model file of it loads only with consent
    runs_code: ClassVar[bool] = True

    system: OdeSystem
    names: tuple[str, ...]
    theta: NDArray[np.float64]
    states: tuple[str, ...]
    x0: NDArray[np.float64]
    estimated: tuple[int, ...]
    dt: float
    substeps: int = 1
    inputs: tuple[str, ...] = ()
    output: str = ""
    units: tuple[str, ...] = ()
    fixed: tuple[bool, ...] = ()
    covariance: NDArray[np.float64] | None = None
    covariance_names: tuple[str, ...] = ()

    @property
    def has_noise_model(self) -> bool:
        """False: the predictor is the simulation (output error)."""
        return False

    def __repr__(self) -> str:
        values = ", ".join(f"{n}={v:.6g}" for n, v in zip(self.names, self.theta, strict=True))
        return (f"OdeModel({self.system.source}: states {', '.join(self.states)}; {values}; "
                f"dt={self.dt!r})")

    def __getitem__(self, name: str) -> float:
        if name not in self.names:
            raise ChannelError(f"no parameter {name!r}; the model has {', '.join(self.names)}")
        return float(self.theta[self.names.index(name)])

    def simulate(self, u: Any, x0: Any = None) -> NDArray[np.float64]:
        """Output from ``x0`` (default the fitted one) under ``u``.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, n_inputs)
            Input, held between samples.
        x0 : array_like, optional
            Initial state (n_states,).

        Returns
        -------
        ndarray, shape (N,) or (N, n_outputs)
            The output (NaN after a divergence).
        """
        uu = self._inputs(u)
        start = self.x0 if x0 is None else as_array("x0", x0, ndim=1)
        if start.size != len(self.states):
            raise DataError(f"x0 needs {len(self.states)} values ({', '.join(self.states)}), "
                            f"got {start.size}")
        ys = self.system.simulate(start, uu, self.theta, self.dt, self.substeps)
        return ys[:, 0] if ys.shape[1] == 1 else ys

    def replay(self, y: Any, u: Any, *, initial: str = "auto") -> tuple[
            NDArray[np.float64], int, str]:
        """Free run on a new record, its initial states refitted.

        Parameters
        ----------
        y : array_like, shape (N,)
            Measured output, used only for the initial states.
        u : array_like, shape (N,) or (N, n_inputs)
            Input.
        initial : {"auto", "estimate", "zero", "measured"}
            ``"auto"``/``"estimate"``: the states estimated in the fit are
            refitted to this record (bounded by their clamps), the others
            keep the declared initial state; ``"zero"``: the declared
            initial state with the estimation record's fitted values, no
            refit.  ``"measured"`` is refused (an ARX rule).

        Returns
        -------
        y_sim : ndarray, shape (N,)
            Simulated output.
        first : int
            First sample the metrics use (0).
        initial : str
            The rule applied (``"estimate"`` or ``"zero"``).
        """
        check_option("initial", initial, _INITIALS)
        if initial == "measured":
            raise ModelError('initial="measured" sets the state from past samples, which only '
                             'an ARX model allows; use initial="estimate" for this model')
        y_arr = as_array("y", y, ndim=1, min_size=2)
        uu = self._inputs(u)
        if uu.shape[0] != y_arr.size:
            raise DataError(f"u has {uu.shape[0]} samples and y {y_arr.size}; give the same "
                            "record's input and output")
        if self.system.n_outputs != 1:
            raise ModelError("the model has several outputs; replay validates one")
        x0 = self.x0.copy()
        if initial == "zero" or not self.estimated:
            return self.system.simulate(x0, uu, self.theta, self.dt, self.substeps)[:, 0], 0, \
                "zero" if initial == "zero" or not self.estimated else "estimate"
        idx = list(self.estimated)
        lo = self.system.state_lower[idx]
        hi = self.system.state_upper[idx]

        def residuals(z: NDArray[np.float64]) -> NDArray[np.float64]:
            x = x0.copy()
            x[idx] = z
            with np.errstate(all="ignore"):
                r = self.system.simulate(x, uu, self.theta, self.dt, self.substeps)[:, 0] - y_arr
            r[~np.isfinite(r)] = _PENALTY
            return r

        start = np.clip(x0[idx], np.nextafter(lo, np.inf), np.nextafter(hi, -np.inf))
        res = optimize.least_squares(residuals, start, bounds=(lo, hi), x_scale="jac",
                                     xtol=1e-10, ftol=1e-10, gtol=1e-10)
        x0[idx] = res.x
        y_sim = self.system.simulate(x0, uu, self.theta, self.dt, self.substeps)[:, 0]
        return y_sim, 0, "estimate"

    def to_dict(self) -> dict[str, Any]:
        """The model as plain data (the functions by name).

        ``model_file`` is the whole servoid model file (:meth:`to_record`
        with its header), or None when a function is not in a file.
        """
        return {"type": "greybox_ode", "model": self.system.source, "dt": self.dt,
                "substeps": self.substeps, "states": list(self.states),
                "parameters": dict(zip(self.names, self.theta.tolist(), strict=True)),
                "initial_state": dict(zip(self.states, self.x0.tolist(), strict=True)),
                "estimate_initial": [self.states[i] for i in self.estimated],
                "compiled": self.system.compiled, "model_file": self._file_record()}

    def to_record(self) -> dict[str, Any]:
        """The model as the plain data of a model file.

        Everything but the file's header (format version, type, ``dt``):
        the reference to the user's code (``model_file``, its
        ``model_sha256``, ``rhs`` and its ``signature``; ``output_file``,
        ``output_sha256`` and ``output_function``, or ``output_state``),
        states, initial state, the states estimated on each record,
        parameters (name, value, unit, fixed), saturations (null: none),
        substeps, ``compiled`` and the covariance.  Never the code.  Floats
        are Python floats, so JSON writes their ``repr`` and
        :meth:`from_record` gets the model back bit for bit.

        Raises
        ------
        ModelError
            A function is not at the top level of a Python file (a lambda,
            a nested function): a saved model could not find it again.
        """
        system = self.system
        rhs_name = system.source.rpartition(":")[2] or getattr(system.rhs, "__name__", "")
        rhs_file, rhs_hash = code_ref(system.rhs, rhs_name, "the right-hand side")
        out: dict[str, Any] = {"output_file": None, "output_sha256": None,
                               "output_function": None, "output_state": None}
        if callable(system.output):
            name = getattr(system.output, "__name__", "")
            out_file, out_hash = code_ref(system.output, name, "the output function")
            out.update(output_file=str(out_file), output_sha256=out_hash, output_function=name)
        else:
            out["output_state"] = int(system.output)
        cov = self.covariance
        finite = cov is not None and bool(np.all(np.isfinite(cov)))
        return {
            "model_file": str(rhs_file), "model_sha256": rhs_hash, "rhs": rhs_name,
            "signature": _SIGNATURES[int(system.takes_time)], **out,
            "compiled": system.compiled, "substeps": self.substeps,
            "states": list(self.states), "initial_state": self.x0.tolist(),
            "estimate_initial": [self.states[i] for i in self.estimated],
            "inputs": list(self.inputs) or [f"u{i + 1}" for i in range(system.n_inputs)],
            "output_name": self.output,
            "parameters": [
                {"name": n, "value": v, "unit": self.units[k] if self.units else "",
                 "fixed": bool(self.fixed[k]) if self.fixed else False}
                for k, (n, v) in enumerate(zip(self.names, self.theta.tolist(), strict=True))],
            "state_saturation": _limits(system.state_lower, system.state_upper),
            "input_saturation": _limits(system.input_lower, system.input_upper),
            "covariance": cov.tolist() if finite else None,  # type: ignore[union-attr]
            "parameter_names": list(self.covariance_names) if finite else None,
        }

    @classmethod
    def check_record(cls, data: Mapping[str, Any], *, where: str = "model file") -> None:
        """Check a model file's data without running any code.

        Parameters
        ----------
        data : mapping
            The file's content (:meth:`to_record` and the header).
        where : str
            The file, for messages.

        Raises
        ------
        FileFormatError
            A key is missing or a value is not what :meth:`to_record` writes.
        """
        _parse(data, where)

    @classmethod
    def from_record(cls, data: Mapping[str, Any], *, allow_code: bool = False,
                    where: str = "model file") -> OdeModel:
        """Rebuild the model, running the user's file only with consent.

        Parameters
        ----------
        data : mapping
            The file's content (:meth:`to_record` and the header).
        allow_code : bool
            Let the user's Python file named in the record run.
        where : str
            The file read, for messages.

        Returns
        -------
        OdeModel
            The model as fitted: same values, same integrator (compiled
            when it was), so ``replay`` gives the same numbers.

        Raises
        ------
        FileFormatError
            The record is damaged.
        OptionError
            ``allow_code`` is not True (nothing is run; the message names
            the Python file).
        MissingFileError
            The Python file is gone.
        ModelError
            The Python file changed since the fit (both SHA-256 named), or
            its code fails.
        """
        rec = _parse(data, where)
        if allow_code is not True:
            files = sorted({str(rec["model_file"]), *([str(rec["output_file"])]
                                                      if rec["output_file"] else [])})
            functions = ", ".join(f for f in (rec["rhs"], rec["output_function"]) if f)
            raise OptionError(
                f"{where} holds a grey-box ODE whose functions ({functions}) are Python code in "
                f"{' and '.join(files)}, and servoid runs a model's code only when told to: "
                "check that file, then load the model with allow_code=True "
                "(servoid.load_model(path, allow_code=True), servoid.load_results(path, "
                "allow_code=True); --allow-code on the command line)")
        modules: dict[Path, Any] = {}
        (rhs,) = load_recorded(rec["model_file"], rec["model_sha256"], [rec["rhs"]], where,
                               modules)
        measure: Any = rec["output_state"]
        out_source, out_key = "", ""
        if rec["output_function"]:
            (measure,) = load_recorded(rec["output_file"], rec["output_sha256"],
                                       [rec["output_function"]], where, modules)
            out_source = f"{rec['output_file'].name}:{rec['output_function']}"
            out_key = f"{rec['output_file']}:{rec['output_function']}"
        lo, hi, ulo, uhi = rec["limits"]
        probe = np.clip(np.zeros((_PROBE, ulo.size)), ulo, uhi)
        probe.setflags(write=False)
        theta = rec["theta"]
        # probed with the array kinds a replay on an Experiment passes (a writable state, a
        # read-only record and parameters): numba compiles one specialisation per kind, and
        # the fit's validation compiled this one already
        system = make_system(
            rhs, measure, x0=rec["x0"].copy(), u=probe, p=theta, state_lower=lo, state_upper=hi,
            input_lower=ulo, input_upper=uhi, source=f"{rec['model_file'].name}:{rec['rhs']}",
            output_source=out_source, path=rec["model_file"], compile=rec["compiled"],
            cache_key=(str(rec["model_file"]), rec["model_sha256"], rec["rhs"], out_key,
                       rec["output_sha256"] or ""))
        if _SIGNATURES[int(system.takes_time)] != rec["signature"]:
            raise ModelError(f"{where}: {system.source} now takes "
                             f"{_SIGNATURES[int(system.takes_time)][3:]}, the record says "
                             f"{rec['signature'][3:]}; fit the model again")
        if rec["compiled"] and not system.compiled:
            warn(f"{where}: the model was fitted with its compiled integrator and is "
                 f"read back with the Python one ({system.note}): replay agrees to "
                 "rounding, not bit for bit", ServoidWarning)
        return cls(system, rec["names"], theta, rec["states"], rec["x0"], rec["estimated"],
                   rec["dt"], rec["substeps"], inputs=rec["inputs"], output=rec["output_name"],
                   units=rec["units"], fixed=rec["fixed"], covariance=rec["covariance"],
                   covariance_names=rec["covariance_names"])

    def _file_record(self) -> dict[str, Any] | None:
        """The whole model file's data, or None when the code cannot be referenced."""
        from ..models import model_record

        try:
            return {**model_record(self), "units": None}
        except ModelError:
            return None

    def _inputs(self, u: Any) -> NDArray[np.float64]:
        uu = as_array("u", u)
        uu = uu[:, None] if uu.ndim == 1 else uu
        if uu.ndim != 2 or uu.shape[1] != self.system.n_inputs:
            raise DataError(f"u must have shape (N, {self.system.n_inputs}) (one column per "
                            f"input of the model), got {uu.shape}")
        return uu


def initial_name(state: str) -> str:
    """The parameter name of a state's estimated initial value."""
    return f"{state}(0)"


def fit_ode(
    data: Experiment,
    system: OdeSystem,
    parameters: Sequence[GreyboxParameter],
    *,
    states: Sequence[str],
    output: str,
    x0: Any,
    estimate_initial: Sequence[str] = (),
    substeps: int = 1,
    covariance: str = "auto",
    multistart: int = 0,
    tol: float = 1e-10,
    max_nfev: int | None = None,
    rng: Any = None,
) -> Estimate:
    """Fit a user's ODE system to one record by simulation error.

    Parameters
    ----------
    data : Experiment
        The record: its "u" channels drive the model, ``output`` is fitted.
    system : OdeSystem
        From :func:`~servoid.estimate._ode.make_system`.
    parameters : sequence of GreyboxParameter
        The model's parameters, in the order ``p`` holds them.
    states : sequence of str
        State names.
    output : str
        The measured output channel.
    x0 : array_like
        Initial state (start values of the estimated entries).
    estimate_initial : sequence of str
        States whose initial value is estimated.
    substeps : int
        RK4 steps per sample.
    covariance : {"auto", "white", "robust", "bootstrap"}
        As :func:`~servoid.estimate.fit_greybox`.
    multistart : int
        Extra random starts.
    tol : float
        Solver tolerance.
    max_nfev : int, optional
        Most solver evaluations (default 100·(n_free + 1)).
    rng : Generator or int, optional
        Random starts and resamples.

    Returns
    -------
    Estimate
        ``model`` is an :class:`OdeModel`; the options add ``inputs``,
        ``output``, ``states``, ``compiled`` and ``integrator_note``.
    """
    if not isinstance(data, Experiment):
        raise type_error("data", data, "an Experiment")
    if not isinstance(system, OdeSystem):
        raise type_error("system", system, "an OdeSystem")
    states = tuple(states)
    x_start = as_array("x0", x0, ndim=1).copy()
    if x_start.size != len(states) or system.n_states != len(states):
        raise DataError(f"x0 needs {len(states)} values ({', '.join(states)}), got "
                        f"{x_start.size}")
    dt = as_float("dt", data.dt, positive=True, unit="s")
    u = data.u if data.u is not None else np.zeros((data.n_samples, 0))
    u = np.ascontiguousarray(np.asarray(u, dtype=float).reshape(data.n_samples, -1))
    params = list(parameters)
    n_model = len(params)
    idx = []
    for name in estimate_initial:
        if name not in states:
            raise DataError(f"estimate_initial names {name!r}, which is not a state; the states "
                            f"are {', '.join(states)}")
        k = states.index(name)
        idx.append(k)
        lo, hi = float(system.state_lower[k]), float(system.state_upper[k])
        params.append(GreyboxParameter(initial_name(name), float(np.clip(x_start[k], lo, hi)),
                                       lo, hi))
    x_base = np.clip(x_start, system.state_lower, system.state_upper)

    def split(theta: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        x = x_base.copy()
        x[idx] = theta[n_model:]
        return theta[:n_model], x

    def simulate(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        p, x = split(theta)
        return system.simulate(x, u, p, dt, substeps)

    est = fit_greybox(data, None, None, params, simulate=simulate, outputs=[output],
                      substeps=substeps, covariance=covariance,  # type: ignore[arg-type]
                      multistart=multistart, tol=tol, max_nfev=max_nfev, rng=rng)
    theta_all = np.asarray(est.model.theta, dtype=float)
    p_fit, x_fit = split(theta_all)
    p_fit = p_fit.copy()
    p_fit.setflags(write=False)
    x_fit.setflags(write=False)
    cov = None if est.covariance is None else np.array(est.covariance, dtype=float)
    model = OdeModel(system, tuple(p.name for p in params[:n_model]), p_fit, states, x_fit,
                     tuple(idx), dt, substeps, inputs=tuple(data.names_of("u")), output=output,
                     units=tuple(p.unit for p in params[:n_model]),
                     fixed=tuple(bool(p.fixed) for p in params[:n_model]), covariance=cov,
                     covariance_names=tuple(est.names))
    options = {**est.options, "input": "u", "inputs": list(data.names_of("u")),
               "output": output, "states": list(states), "integrator": "rk4",
               "compiled": system.compiled, "integrator_note": system.note,
               "model": system.source}
    return dataclasses.replace(est, model=model, options=options)


# -- private ----------------------------------------------------------------------------------


def _limits(lower: NDArray[np.float64], upper: NDArray[np.float64]) -> list[list[float | None]]:
    """Saturations as ``[lower, upper]`` pairs, null for no limit (JSON has no inf)."""
    return [[None if np.isinf(lo) else float(lo), None if np.isinf(hi) else float(hi)]
            for lo, hi in zip(lower.tolist(), upper.tolist(), strict=True)]


def _parse(data: Mapping[str, Any], where: str) -> dict[str, Any]:
    """A grey-box model record's values, checked; FileFormatError when damaged."""
    fix = "write the model file again from the fit (servoid.models.save_model)"
    try:
        return _values(data)
    except KeyError as exc:
        raise FileFormatError(f"{where}: the OdeModel has no {exc.args[0]!r}; the file is "
                              f"damaged: {fix}") from None
    except (TypeError, ValueError, AttributeError, IndexError) as exc:
        raise FileFormatError(f"{where}: the OdeModel is damaged ({exc}); {fix}") from None


def _values(data: Mapping[str, Any]) -> dict[str, Any]:
    def text(key: str, *, optional: bool = False) -> Any:
        value = data[key]
        if value is None and optional:
            return None
        if not isinstance(value, str) or not value:
            raise ValueError(f"{key} must be a text, got {value!r}")
        return value

    def names(key: str) -> tuple[str, ...]:
        value = data[key]
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise ValueError(f"{key} must be a list of names, got {value!r}")
        return tuple(value)

    def digest(key: str) -> str:
        value = text(key)
        if len(value) != 64 or any(c not in "0123456789abcdef" for c in value):
            raise ValueError(f"{key} must be a SHA-256 in hex, got {value!r}")
        return str(value)

    def floats(values: Any, key: str, size: int) -> NDArray[np.float64]:
        if not isinstance(values, list) or len(values) != size or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            raise ValueError(f"{key} must be {size} numbers, got {values!r}")
        arr = np.array(values, dtype=float)
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{key} must be finite, got {values!r}")
        arr.setflags(write=False)
        return arr

    def limits(key: str, size: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        pairs = data[key]
        if not isinstance(pairs, list) or len(pairs) != size:
            raise ValueError(f"{key} must hold {size} [lower, upper] pairs, got {pairs!r}")
        lo, hi = np.full(size, -np.inf), np.full(size, np.inf)
        for k, pair in enumerate(pairs):
            if not isinstance(pair, list) or len(pair) != 2 or not all(
                    v is None or (isinstance(v, (int, float)) and not isinstance(v, bool))
                    for v in pair):
                raise ValueError(f"{key} must hold [lower, upper] pairs (null: none), got "
                                 f"{pair!r}")
            if pair[0] is not None:
                lo[k] = pair[0]
            if pair[1] is not None:
                hi[k] = pair[1]
            if not lo[k] < hi[k]:
                raise ValueError(f"{key}: lower {lo[k]:g} must be below upper {hi[k]:g}")
        return lo, hi

    dt = as_float("dt", data["dt"], positive=True, unit="s")
    model_file = Path(text("model_file"))
    if not model_file.is_absolute() or model_file.suffix != ".py":
        raise ValueError(f"model_file must be the absolute path of a .py file, got "
                         f"{str(model_file)!r}")
    signature = data["signature"]
    if signature not in _SIGNATURES:
        raise ValueError(f"signature must be one of {', '.join(_SIGNATURES)}, got {signature!r}")
    out_fn = text("output_function", optional=True)
    if out_fn is not None:
        out_file, out_hash, out_state = Path(text("output_file")), digest("output_sha256"), None
        if not out_file.is_absolute() or out_file.suffix != ".py":
            raise ValueError(f"output_file must be the absolute path of a .py file, got "
                             f"{str(out_file)!r}")
    else:
        out_file, out_hash, out_state = None, None, data["output_state"]
    states = names("states")
    if not states or len(set(states)) != len(states):
        raise ValueError(f"states must name each state once, got {list(states)}")
    if out_state is not None and (isinstance(out_state, bool) or not isinstance(out_state, int)
                                  or not 0 <= out_state < len(states)):
        raise ValueError(f"output_state must be a state index below {len(states)}, got "
                         f"{out_state!r}")
    estimated = names("estimate_initial")
    unknown = [n for n in estimated if n not in states]
    if unknown:
        raise ValueError(f"estimate_initial names {unknown}, not states")
    inputs = names("inputs")
    rows = data["parameters"]
    if not isinstance(rows, list) or not rows or not all(
            isinstance(r, Mapping) and isinstance(r.get("name"), str)
            and isinstance(r.get("unit", ""), str) and isinstance(r.get("fixed", False), bool)
            for r in rows):
        raise ValueError("parameters must be a list of {name, value, unit, fixed}")
    theta = floats([r["value"] for r in rows], "parameters' values", len(rows))
    substeps = data["substeps"]
    if isinstance(substeps, bool) or not isinstance(substeps, int) or substeps < 1:
        raise ValueError(f"substeps must be an integer >= 1, got {substeps!r}")
    compiled = data["compiled"]
    if not isinstance(compiled, bool):
        raise TypeError(f"compiled must be true or false, got {compiled!r}")
    output_name = data.get("output_name") or ""
    if not isinstance(output_name, str):
        raise TypeError(f"output_name must be a text, got {output_name!r}")
    cov, cov_names = data.get("covariance"), data.get("parameter_names")
    if cov is not None:
        cov = as_array("covariance", cov, ndim=2)
        if cov.shape[0] != cov.shape[1]:
            raise ValueError(f"covariance must be a square matrix, got shape {cov.shape}")
        if cov_names is not None and (not isinstance(cov_names, list) or len(cov_names) !=
                                      cov.shape[0]):
            raise ValueError(f"parameter_names must name the {cov.shape[0]} rows of the "
                             f"covariance, got {cov_names!r}")
    return {
        "dt": dt, "model_file": model_file, "model_sha256": digest("model_sha256"),
        "rhs": _identifier(text("rhs")), "signature": signature,
        "output_function": None if out_fn is None else _identifier(out_fn),
        "output_file": out_file, "output_sha256": out_hash, "output_state": out_state,
        "states": states, "x0": floats(data["initial_state"], "initial_state", len(states)),
        "estimated": tuple(states.index(n) for n in estimated), "inputs": inputs,
        "output_name": output_name,
        "names": tuple(r["name"] for r in rows), "theta": theta,
        "units": tuple(r.get("unit", "") for r in rows),
        "fixed": tuple(r.get("fixed", False) for r in rows),
        "limits": (*limits("state_saturation", len(states)),
                   *limits("input_saturation", len(inputs))),
        "substeps": substeps, "compiled": compiled, "covariance": cov,
        "covariance_names": tuple(str(n) for n in cov_names or ()) if cov is not None else (),
    }


def _identifier(name: str) -> str:
    if not name.isidentifier():
        raise ValueError(f"{name!r} is not a function name")
    return name
