"""Every method ``[identify] method = …`` can name: one line each.

A line gives the method's name, where its :class:`Method` is defined and
its one-line summary.  The module is imported when the method is first
asked for (``METHODS[name]``), so that listing the methods
(``servoid methods``) imports none of them and a run imports only its own.
The summary is repeated here for that listing; a test checks that every
line agrees with its module's :class:`Method`.  A plant's methods come
with its record (:data:`servoid.plants.PLANTS`: each method's name and
summary, and where its ``Method`` objects are): registering a plant
registers them.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping
from typing import Any

from .._errors import check_option
from ._registry import Method

__all__ = ["DEFAULT_METHOD", "METHODS", "get_method", "method_names", "method_of"]

#: The method an ``[identify]`` table without ``method`` runs.
DEFAULT_METHOD = "arx"

#: name, "module:attribute" of its Method, summary — in the order ``servoid methods`` lists them
_LISTED: tuple[tuple[str, str, str], ...] = (
    ("arx", "_arx:METHOD",
     "ARX model A y = B u + e by least squares, with covariance; orders given or searched "
     "over a grid"),
    ("oe", "_pem:OE",
     "output-error model y = B/F u + e by prediction error (exact gradient), with "
     "covariance; the best simulation model"),
    ("armax", "_pem:ARMAX",
     "ARMAX model A y = B u + C e by prediction error, with covariance; a noise model "
     "sharing the plant's poles"),
    ("bj", "_pem:BJ",
     "Box–Jenkins model y = B/F u + C/D e by prediction error, with covariance; "
     "independent plant and noise models (also the direct method on closed-loop data)"),
    ("tf", "_tf:TF",
     "continuous transfer function (poles, zeros, input delay) by refined instrumental "
     "variables (SRIVC; CLSRIVC with the reference as instrument), with gain, ω_n, ζ ± σ"),
    ("n4sid", "_n4sid:N4SID",
     "state-space model by subspace projection (MOESP, CVA, N4SID), SISO or MIMO, order "
     "from the singular values; optionally refined by output error"),
    ("frf", "_frf:FRF",
     "measured frequency response (Welch H1 with coherence, or averaged over excitation "
     "periods with its variance), the spec numbers, and optionally a continuous transfer "
     "function fitted to it"),
    ("frequency", "_frequency:FREQUENCY",
     "frequency response with its variance (BLA of a multisine test with noise and "
     "nonlinear-distortion variances, or the local polynomial method), a transfer function "
     "by maximum likelihood with its order from the cost test, and the acceptance numbers "
     "with 95 % intervals"),
    ("two-stage", "_closedloop_any:TWO_STAGE",
     "plant from a closed-loop record with an unknown controller: a FIR r → u gives the "
     "noise-free input, then OE (or BJ) from it to y"),
    ("cliv", "_closedloop_any:CLIV",
     "plant from a closed-loop record with an unknown controller by instrumental "
     "variables built from the reference"),
    ("indirect", "_closedloop_any:INDIRECT",
     "plant of any order from a closed-loop record and the known controller ([loop] "
     "controller, feedback): OE of r → y, then the plant"),
    ("closedloop-auto", "_closedloop_auto:CLOSEDLOOP_AUTO",
     "plant from a closed-loop record: the loop's known facts (reference, controller, "
     "stability) pick the closed-loop methods, run side by side, the most informative "
     "consistent one kept"),
    ("hammerstein", "_blocks:HAMMERSTEIN",
     "Hammerstein model y = G(q)·f(u) + e: a static curve (dead zone, saturation, …) "
     "before a linear block, jointly by output error"),
    ("wiener", "_blocks:WIENER",
     "Wiener model y = g(G(q)·u) + e: a linear block before a static curve (|x|, "
     "saturation, …), jointly by output error"),
    ("hammerstein-wiener", "_blocks:HAMMERSTEIN_WIENER",
     "Hammerstein–Wiener model y = g(G(q)·f(u)) + e: static curves on both sides of a "
     "linear block"),
    ("narx", "_narx:METHOD",
     "polynomial NARX y(t) = Σ θ·(products of lagged y and u) + e: terms chosen by "
     "forward orthogonal least squares (ERR) and BIC/AIC, validated by free run"),
    ("pnlss", "_pnlss:METHOD",
     "polynomial nonlinear state space x⁺ = Ax + Bu + Eζ(x, u), y = Cx + Du + Fη(x, u) "
     "from a linear start, by Levenberg–Marquardt on the simulation error; states and "
     "degree from a grid on held-out data"),
    ("greybox", "_greybox:GREYBOX",
     "a grey-box ODE written in Python (model = \"file.py:rhs\"), its parameters and "
     "initial states fitted by simulation error with bounds, saturations, multistart and "
     "identifiability checks; needs --allow-code"),
)


def method_names() -> tuple[str, ...]:
    """Names ``[identify] method`` accepts, in registry order."""
    return tuple(METHODS)


def method_of(identify: Mapping[str, Any] | None) -> Any:
    """The method an ``[identify]`` table names (:data:`DEFAULT_METHOD` without one), as given.

    A value that names no method is left for :func:`get_method` to refuse.
    """
    return (identify or {}).get("method", DEFAULT_METHOD)


def get_method(name: str) -> Method:
    """Return the registered method called ``name``.

    Raises
    ------
    OptionError
        No such method; the message lists the registered ones.
    """
    check_option("[identify] method", name, METHODS)
    return METHODS[name]


class _Methods(Mapping[str, Method]):
    """Read-only name → :class:`Method`, each imported on first use."""

    def __init__(self, listed: tuple[tuple[str, str, str], ...]) -> None:
        self._where = {name: where for name, where, _ in listed}
        self._summary = {name: summary for name, _, summary in listed}
        # The plants build their methods with this package's kit; their records are read by
        # name (as every method module is), so workflows never imports a plant's code.
        self._plants = plants = importlib.import_module("servoid.plants").PLANTS
        for plant in plants.values():  # "plant:<name>": one of the plant's methods
            for name, summary in plant.methods.items():
                self._where.setdefault(name, f"plant:{plant.name}")
                self._summary.setdefault(name, summary)
        if len(self._where) != len(listed) + sum(len(p.methods) for p in plants.values()):
            raise ValueError("a method is listed twice")
        self._loaded: dict[str, Method] = {}

    def __getitem__(self, name: str) -> Method:
        if name not in self._loaded:
            module, attribute = self._where[name].split(":")  # KeyError: not a method
            if module == "plant":
                method = next((m for m in self._plants[attribute].load("methods")
                               if m.name == name), None)
            else:
                method = getattr(importlib.import_module(f".{module}", __package__), attribute)
            if not isinstance(method, Method) or method.name != name:
                raise TypeError(f"{module}:{attribute} has no Method {name!r}")
            self._loaded[name] = method
        return self._loaded[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._where)

    def __len__(self) -> int:
        return len(self._where)

    def summary(self, name: str) -> str:
        """The method's one line, without importing it."""
        return self._summary[name]


#: every method, in the order ``servoid methods`` lists them
METHODS = _Methods(_LISTED)
