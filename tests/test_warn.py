"""servoid's warnings name the caller's line, whatever the depth inside servoid."""

from __future__ import annotations

import re
import sys
import types
import warnings
from pathlib import Path

import numpy as np
import pytest

import servoid
from servoid import ServoidWarning
from servoid.signals import multisine
from servoid.validate import relative_error, vaf

SRC = Path(servoid.__file__).parent


def _caught(call):  # type: ignore[no-untyped-def]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        call()
    return [w for w in caught if issubclass(w.category, ServoidWarning)]


@pytest.mark.parametrize("call", [
    lambda: relative_error(np.zeros(8), np.ones(8)),  # warns in the public function itself
    lambda: vaf(np.ones(8), np.arange(8.0)),  # in a private helper it calls
    lambda: multisine(1000, 1e-3, 2.0, 2.5),  # only one line in the band
], ids=["relative_error", "vaf", "multisine"])
def test_a_public_function_warns_at_the_callers_line(call):
    caught = _caught(call)
    assert caught
    for w in caught:
        assert w.filename == __file__, (w.filename, str(w.message))


def test_through_another_library_the_outermost_servoid_call_is_named():
    """servoid → a solver (not servoid) → servoid → warn: the user's line, not the solver's."""
    from servoid._warn import warn

    solver = types.ModuleType("a_solver")  # stands for scipy calling a residual function back
    exec("def minimise(fn):\n    return fn()\n", solver.__dict__)  # noqa: S102
    inner = {"__name__": "servoid._fake_residual", "warn": warn}
    exec("def residual():\n    warn('the residual is flat')\n", inner)  # noqa: S102
    outer = {"__name__": "servoid._fake_fit", "solver": solver, "residual": inner["residual"]}
    exec("def fit():\n    return solver.minimise(residual)\n", outer)  # noqa: S102
    line = sys._getframe().f_lineno + 1
    caught = _caught(lambda: outer["fit"]())
    assert [(w.filename, w.lineno) for w in caught] == [(__file__, line)]


def test_every_warning_in_the_package_goes_through_the_helper():
    calls = [f"{path.relative_to(SRC)}:{n}" for path in sorted(SRC.rglob("*.py"))
             if path.name != "_warn.py"
             for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
             if re.search(r"\bwarnings\.warn\(", line)]
    assert calls == [], "use servoid._warn.warn, which names the caller's line: " + \
        ", ".join(calls)
