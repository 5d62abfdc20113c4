"""One fixed-step RK4 integrator for a user's ODE, compiled when it can be.

The user writes the physics as plain Python::

    def rhs(x, u, p):          # or rhs(t, x, u, p)
        return dx/dt           # one entry per state

    def out(x, u, p):          # optional; default: the first state
        return y               # a number (or one entry per output)

with ``x`` the state (nx,), ``u`` the input at the sample (m,), ``p`` every
parameter in the order they are declared, and ``t`` the time since the
record's first sample [s].  :func:`make_system` wraps them in an
:class:`OdeSystem` whose ``simulate`` runs fixed-step RK4 with ``substeps``
steps per sample period, the input held between samples (zero-order hold,
as a DAC holds it), and declared saturations:

- an **input saturation** ``[lo, hi]`` clips the logged input before the
  right-hand side sees it (a valve or pump that saturates);
- a **state saturation** ``[lo, hi]`` is a clamp (overflow, a full tank):
  at a limit the state's outward rate is zero inside every RK4 stage, and
  after each step the state is projected back onto its range.  A clamp, not
  an impact: a mechanical end stop that must also stop a velocity state is
  written into ``rhs``.

There is one integrator source (:func:`_make_kernel`).  It is compiled with
numba when the user's functions compile (``numba.njit`` in nopython mode,
``error_model="numpy"`` so that 1/0 gives inf like numpy instead of
raising) and the compiled and the plain results agree on the first
samples; otherwise the same source runs as Python, with a one-line note in
:attr:`OdeSystem.note`.  Errors raised by the user's code become
:class:`~servoid.ModelError` naming the file, the line and the function
(:func:`user_error`).
"""

from __future__ import annotations

import inspect
import math
import re
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._errors import ModelError
from ..integrate import rk4_step

__all__ = ["OdeSystem", "make_system", "simulation_seconds", "user_error"]

#: samples the compiled and the Python integrators are compared on
_PROBE = 8
#: compiled kernels by the caller's key (file, its SHA-256, function names): a fleet of
#: records, or a second run in one process, compiles a model file once
_COMPILED: dict[tuple[Any, ...], Callable[..., Any]] = {}
_MAX_COMPILED = 16


@dataclass(frozen=True, eq=False)
class OdeSystem:
    """A user's ODE with its integrator, compiled or plain.

    Attributes
    ----------
    rhs : callable
        The user's right-hand side.
    output : callable or int
        The user's output function, or the index of the measured state.
    n_states, n_inputs, n_outputs : int
        Sizes.
    takes_time : bool
        ``rhs(t, x, u, p)`` rather than ``rhs(x, u, p)``.
    state_lower, state_upper : ndarray
        State clamps (±inf for none), (nx,).
    input_lower, input_upper : ndarray
        Input saturations (±inf for none), (m,).
    compiled : bool
        The numba kernel runs; False: the Python integrator.
    note : str
        Why the Python integrator runs ('' when compiled).
    source : str
        ``"file.py:function"``, for messages.
    """

    rhs: Callable[..., Any]
    output: Callable[..., Any] | int
    n_states: int
    n_inputs: int
    n_outputs: int
    takes_time: bool
    state_lower: NDArray[np.float64]
    state_upper: NDArray[np.float64]
    input_lower: NDArray[np.float64]
    input_upper: NDArray[np.float64]
    compiled: bool
    note: str
    source: str
    path: Path | None = field(default=None, repr=False)
    _kernel: Callable[..., Any] | None = field(default=None, repr=False)
    _plain: Callable[..., Any] | None = field(default=None, repr=False)

    def simulate(self, x0: NDArray[np.float64], u: NDArray[np.float64],
                 p: NDArray[np.float64], dt: float, substeps: int) -> NDArray[np.float64]:
        """Outputs (N, n_outputs) from ``x0`` under the input ``u``.

        Samples after a divergence (a non-finite state) are NaN.  Inputs
        are trusted (the fits check them at their boundary).
        """
        ys = np.empty((u.shape[0], self.n_outputs))
        assert self._kernel is not None
        args = (np.ascontiguousarray(x0, dtype=float), np.ascontiguousarray(u, dtype=float),
                np.ascontiguousarray(p, dtype=float), float(dt), int(substeps),
                self.state_lower, self.state_upper, self.input_lower, self.input_upper)
        try:
            self._kernel(*args, ys)
        except ModelError:
            raise
        except (Exception, SystemExit) as exc:  # noqa: BLE001 — the user's code failed: say where
            if self.compiled and self._plain is not None:
                # compiled code keeps no line numbers: the same step in Python names the line
                try:
                    self._plain(*args, np.empty_like(ys))
                except (Exception, SystemExit) as plain_exc:  # noqa: BLE001
                    raise user_error(plain_exc, self.source, self.path) from None
            raise user_error(exc, self.source, self.path) from None
        return ys


def make_system(
    rhs: Callable[..., Any],
    output: Callable[..., Any] | int,
    *,
    x0: NDArray[np.float64],
    u: NDArray[np.float64],
    p: NDArray[np.float64],
    state_lower: NDArray[np.float64],
    state_upper: NDArray[np.float64],
    input_lower: NDArray[np.float64],
    input_upper: NDArray[np.float64],
    source: str,
    output_source: str = "",
    path: Path | None = None,
    compile: bool = True,
    cache_key: tuple[Any, ...] | None = None,
) -> OdeSystem:
    """Check the user's functions and build their integrator.

    Parameters
    ----------
    rhs : callable
        ``rhs(x, u, p)`` or ``rhs(t, x, u, p)`` returning dx/dt (nx,).
    output : callable or int
        ``output(x, u, p)`` returning a number or (n_outputs,); or a state
        index.
    x0, u, p : ndarray
        A probe: initial state (nx,), the record's input (N, m), every
        parameter.  ``rhs`` and ``output`` are called on them once.
    state_lower, state_upper, input_lower, input_upper : ndarray
        Clamps and saturations (±inf for none).
    source, output_source : str
        ``"file.py:function"`` of each, for messages.
    path : Path, optional
        The user's file (errors name its lines).
    compile : bool
        Try numba; False: the Python integrator.
    cache_key : tuple, optional
        Identifies the functions' source (e.g. the file's path and
        SHA-256): a kernel compiled under the same key is reused.

    Returns
    -------
    OdeSystem

    Raises
    ------
    ModelError
        A function with the wrong arguments, one that raises on the probe
        (naming the file and line), or returns the wrong shape or type.
    """
    n_states = x0.size
    n_inputs = u.shape[1]
    takes_time = _arity(rhs, source, ("x, u, p", "t, x, u, p")) == 4
    x_probe = np.clip(x0, state_lower, state_upper)
    u_probe = np.clip(u[0], input_lower, input_upper)
    args = ((0.0,) if takes_time else ()) + (x_probe, u_probe, p)
    rates = _call(rhs, args, source, path)
    rates = _numbers(rates, source, "dx/dt")
    if rates.shape != (n_states,):
        raise ModelError(
            f"{source} returned dx/dt of shape {rates.shape} for {n_states} states; return one "
            f"rate per state, e.g. (dx0, dx1) or np.array([dx0, dx1])")
    if callable(output):
        if _arity(output, output_source, ("x, u, p",)) != 3:
            raise ModelError(f"{output_source} must take (x, u, p)")
        y = _numbers(_call(output, (x_probe, u_probe, p), output_source, path),
                     output_source, "the output")
        if y.ndim > 1 or y.size < 1:
            raise ModelError(f"{output_source} returned an output of shape {y.shape}; return a "
                             "number (one measured output) or one number per output")
        n_outputs, kind = (1, "scalar") if y.ndim == 0 else (y.size, "vector")
    else:
        n_outputs, kind = 1, "index"
    bounds = tuple(np.ascontiguousarray(b, dtype=float)
                   for b in (state_lower, state_upper, input_lower, input_upper))
    plain = _make_kernel(rhs, output, takes_time, kind, n_states, jit=False)
    system = OdeSystem(rhs, output, n_states, n_inputs, n_outputs, takes_time, *bounds,
                       compiled=False, note="", source=source, path=path, _kernel=plain,
                       _plain=plain)
    if not compile:
        return _replace(system, note="compile = false: the Python integrator runs")
    probe_u = np.ascontiguousarray(u[:_PROBE], dtype=float)
    expected = system.simulate(x0, probe_u, p, 1e-3, 1)
    key = None if cache_key is None else (*cache_key, takes_time, kind)
    try:
        import numba  # noqa: F401 — a missing numba is one more reason for the Python path

        fast = _COMPILED.get(key) if key is not None else None
        if fast is None:
            fast = _make_kernel(rhs, output, takes_time, kind, n_states, jit=True)
        got = np.empty_like(expected)
        fast(np.ascontiguousarray(x0, dtype=float), probe_u, np.ascontiguousarray(p, dtype=float),
             1e-3, 1, *bounds, got)
    except Exception as exc:  # noqa: BLE001 — numba fails in many ways: any failure falls back
        return _replace(system, note=f"{source} does not compile with numba ({_why(exc)}); the "
                        "Python integrator runs (much slower)")
    if not np.allclose(got, expected, rtol=1e-9, atol=1e-300, equal_nan=True):
        return _replace(system, note=f"{source} gives other numbers compiled than in Python; the "
                        "Python integrator runs (much slower)")
    if key is not None:
        if len(_COMPILED) >= _MAX_COMPILED:
            _COMPILED.pop(next(iter(_COMPILED)))
        _COMPILED[key] = fast
    return _replace(system, compiled=True, _kernel=fast)


def simulation_seconds(system: OdeSystem, x0: NDArray[np.float64], u: NDArray[np.float64],
                       p: NDArray[np.float64], dt: float, substeps: int, *,
                       budget: float = 0.05) -> float:
    """Seconds one simulation over all of ``u`` takes, from timing its first samples.

    Simulates 16 samples, then four times more each round until a round
    takes ``budget`` seconds or covers the record, and extrapolates by the
    number of steps: a small part of one simulation, even for the Python
    integrator.
    """
    n = u.shape[0]
    k = min(n, 16)
    while True:
        start = time.perf_counter()
        system.simulate(x0, u[:k], p, dt, substeps)
        took = time.perf_counter() - start
        if took >= budget or k >= n:
            return took * max(n - 1, 1) / max(k - 1, 1)
        k = min(n, 4 * k)


def user_error(exc: BaseException, source: str, path: Path | None) -> ModelError:
    """A ModelError naming the user's file, line and error."""
    where = source
    if isinstance(exc, SyntaxError) and exc.lineno is not None:
        where = f"{Path(exc.filename or source).name}, line {exc.lineno}"
    elif path is not None:
        frames = [f for f in traceback.extract_tb(exc.__traceback__)
                  if Path(f.filename).resolve() == path.resolve()]
        if frames:
            f = frames[-1]
            where = f"{path.name}, line {f.lineno}, in {f.name}"
            if f.line:
                where += f": {f.line.strip()}"
    if isinstance(exc, SystemExit):  # sys.exit() would end servoid with no results
        return ModelError(f"the model code called sys.exit({exc.code!r}) ({where}): a model "
                          "function must return its values, not end the program; remove the "
                          "call (raise an exception to report a problem)")
    message = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    return ModelError(f"the model code failed ({where}): {type(exc).__name__}"
                      + (f": {message}" if message else ""))


# -- private ------------------------------------------------------------------------------


def _replace(system: OdeSystem, **changes: Any) -> OdeSystem:
    import dataclasses

    return dataclasses.replace(system, **changes)


def _why(exc: BaseException) -> str:
    """numba's reason in one line, with the user's line it names ("Failed in …" skipped)."""
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
    reason = next((line for line in lines if not line.startswith("Failed in ")),
                  lines[0] if lines else type(exc).__name__)[:160]
    here = Path(__file__).name
    for line in lines:
        found = re.match(r'File "(.+)", line (\d+):', line)
        if found and Path(found[1]).name != here:
            return f"{reason}; {Path(found[1]).name}, line {found[2]}"
    return reason


def _arity(fn: Callable[..., Any], source: str, forms: tuple[str, ...]) -> int:
    """Number of positional parameters, checked against the forms."""
    try:
        params = inspect.signature(fn).parameters.values()
    except (TypeError, ValueError):
        raise ModelError(f"{source} is not a Python function servoid can inspect") from None
    positional = [q for q in params if q.kind in (q.POSITIONAL_ONLY, q.POSITIONAL_OR_KEYWORD)
                  and q.default is q.empty]
    allowed = {len(f.split(", ")) for f in forms}
    if len(positional) not in allowed:
        listed = " or ".join(f"({f})" for f in forms)
        raise ModelError(f"{source} takes {len(positional)} arguments; it must take {listed}")
    return len(positional)


def _call(fn: Callable[..., Any], args: tuple[Any, ...], source: str, path: Path | None) -> Any:
    try:
        with np.errstate(all="ignore"):
            return fn(*args)
    except (Exception, SystemExit) as exc:  # noqa: BLE001 — user code may raise anything
        raise user_error(exc, source, path) from None


def _numbers(value: Any, source: str, what: str) -> NDArray[np.float64]:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"{source} returned {type(value).__name__} {value!r:.80}; {what} must "
                         "be numbers") from None
    return arr


def _make_kernel(rhs: Callable[..., Any], output: Callable[..., Any] | int, takes_time: bool,
                 kind: str, nx: int, *, jit: bool) -> Callable[..., Any]:
    """The RK4 integrator over the user's functions, plain or compiled.

    The integrator carries the state as a tuple of ``nx`` floats (unrolled
    arithmetic, nothing allocated per step) and hands the user's functions
    an array holding it.
    """
    if jit:
        import numba

        def dec(fn: Callable[..., Any]) -> Any:
            return numba.njit(error_model="numpy")(fn)
    else:
        def dec(fn: Callable[..., Any]) -> Any:
            return fn

    user = dec(rhs)
    if takes_time:
        def f(t: float, x: Any, u: Any, p: Any) -> Any:
            return user(t, x, u, p)
    else:
        def f(t: float, x: Any, u: Any, p: Any) -> Any:
            return user(x, u, p)
    f = dec(f)
    if kind == "index":
        index = int(output)  # type: ignore[arg-type]

        def write(x: Any, u: Any, p: Any, ys: Any, k: int) -> None:
            ys[k, 0] = x[index]
    else:
        measure = dec(output)
        if kind == "scalar":
            def write(x: Any, u: Any, p: Any, ys: Any, k: int) -> None:
                ys[k, 0] = measure(x, u, p)
        else:
            def write(x: Any, u: Any, p: Any, ys: Any, k: int) -> None:
                o = measure(x, u, p)
                for i in range(ys.shape[1]):
                    ys[k, i] = o[i]
    write = dec(write)

    as_state, fill, rates_of, project = _state_helpers(nx, dec, jit)

    def rates(t: float, x: Any, uk: Any, ctx: Any) -> Any:
        p, lo, hi, xa = ctx
        fill(xa, x)
        return rates_of(f(t, xa, uk, p), x, lo, hi)

    def clamp(t: float, x: Any, before: Any, uk: Any, ctx: Any) -> Any:
        return project(x, ctx[1], ctx[2])

    rates = dec(rates)
    clamp = dec(clamp)
    step = rk4_step if jit else rk4_step.py_func

    def kernel(x0: Any, u: Any, p: Any, dt: float, substeps: int, lo: Any, hi: Any,
               ulo: Any, uhi: Any, ys: Any) -> None:
        n, m = u.shape
        xa = np.empty(nx)  # the state as the user's functions see it: an array
        uk = np.empty(m)
        x = project(as_state(x0), lo, hi)
        ctx = (p, lo, hi, xa)
        h = dt / substeps
        for k in range(n):
            for j in range(m):
                uk[j] = min(max(u[k, j], ulo[j]), uhi[j])
            fill(xa, x)
            write(xa, uk, p, ys, k)
            if k == n - 1:
                break
            for s in range(substeps):
                x, _ = step(rates, clamp, (k * substeps + s) * h, x, uk, ctx, h)
            finite = True
            for i in range(nx):
                if not math.isfinite(x[i]):
                    finite = False
            if not finite:  # diverged: the rest is NaN, and the fit rejects the step
                for kk in range(k + 1, n):
                    for i in range(ys.shape[1]):
                        ys[kk, i] = np.nan
                return

    return dec(kernel)


def _state_helpers(nx: int, dec: Callable[..., Any], jit: bool
                   ) -> tuple[Callable[..., Any], ...]:
    """``as_state``, ``fill``, ``rates_of`` and ``project`` for ``nx`` states, through ``dec``.

    Written out for the state's size, so that the compiled integrator keeps
    the state in registers: ``as_state(a)`` is the tuple of an array,
    ``fill(xa, x)`` copies the tuple into the user's array,
    ``rates_of`` turns what the user returned into a tuple of rates, zero
    where a clamped state would move further out (overflow, a full tank),
    ``project`` puts the state back onto its range after a step.  Compiled,
    the rate test is a function (numba inlines it); in Python it is written
    out, a call per state costing more than the test.
    """
    idx = range(nx)
    rate = ("_rate(d[{i}], x[{i}], lo[{i}], hi[{i}]), " if jit else
            "0.0 if (x[{i}] >= hi[{i}] and d[{i}] > 0.0) or (x[{i}] <= lo[{i}] and "
            "d[{i}] < 0.0) else float(d[{i}]), ")
    source = (
        "def as_state(a):\n    return (" + "".join(f"a[{i}], " for i in idx) + ")\n"
        "def fill(xa, x):\n"
        + "".join(f"    xa[{i}] = x[{i}]\n" for i in idx)
        + "def rates_of(d, x, lo, hi):\n    return ("
        + "".join(rate.format(i=i) for i in idx) + ")\n"
        + "def project(x, lo, hi):\n    return ("
        + "".join(f"min(max(x[{i}], lo[{i}]), hi[{i}]), " for i in idx) + ")\n"
    )
    namespace: dict[str, Any] = {"_rate": dec(_rate)}
    exec(source, namespace)  # noqa: S102 — text built here from an integer
    return tuple(dec(namespace[name]) for name in ("as_state", "fill", "rates_of", "project"))


def _rate(r: float, x: float, lo: float, hi: float) -> float:
    """A state's rate, zero where it sits at a clamp and would move further out."""
    if (x >= hi and r > 0.0) or (x <= lo and r < 0.0):
        return 0.0
    return float(r)
